"""The minimisation of one ``barrier`` step: scripted nodes, warm start, the friction loop.

``ScriptedSolve.solve`` brings scripted nodes to their end-of-step positions without crossing
(part-way moves filtered by CCD), optionally warm-starts Newton from a prediction, and runs the
outer lagged-friction loop of Algorithm 1 around ``solvers.newton.minimize``. Everything a solve
needs is passed in; what it returns is the Newton result with the iterations and per-phase timings
of every minimisation of the step summed (plus the phases ``friction``: lagging and the
friction loop's stopping test, and ``scripted_ccd``: the sub-steps' CCD), the lagged-friction
updates of the step (the most of any one sub-step's loop, so within the cap
``contact.friction_iterations``) and whether every friction loop converged.
"""

from __future__ import annotations

import logging
import time
from typing import Any

import numpy as np

from bfemp.state import State
from bfemp.steppers._scaffold import StepNodes
from bfemp.steppers.base import StepError
from solvers.assembly import TripletAssembler
from solvers.linear import LinearSolver
from solvers.newton import minimize
from solvers.result import TIMING_KEYS, NewtonResult, add_timings

__all__ = ["ScriptedSolve"]

log = logging.getLogger(__name__)


class ScriptedSolve:
    """The minimisation of a ``barrier`` step (see the module docstring); keeps only the
    triplet assembler (the Hessian's sparsity pattern) from step to step.

    Args:
        owner: the stepper it solves for (``barrier``, ``two_stage``); taken from it: ``model``,
            ``potential`` (begun for each step by the owner), the ``barrier`` and ``friction``
            terms (or None), the ``newton`` options (``step_scale`` = dt) and ``dt`` in s.
        linear_solver: the linear solver.
        take_last_increment: end a converged friction loop at the solution of the friction data
            it stopped on (``_take``); for velocities from positions.
        friction_loop: run the outer friction loop on the step's last solve (Algorithm 1);
            False: friction lagged once, one minimisation (``two_stage``'s semi-implicit
            friction).
        back_solve_stop: the loop's stopping test by a back-solve (``_increment_below_tol``,
            ``BarrierOptions.friction_back_solve``); False: by a Newton iteration.
    """

    #: cap of the part-way moves of scripted nodes within one step
    SCRIPTED_SUBSTEPS = 64
    #: the friction loop stops, unconverged, when ``STALL_WINDOW`` re-solves in a row each move
    #: the unknowns by more than ``STALL_FACTOR`` x the least move before them (``stalled``)
    STALL_WINDOW, STALL_FACTOR = 3, 0.5

    def __init__(
        self,
        owner: Any,
        linear_solver: LinearSolver,
        *,
        take_last_increment: bool = True,
        friction_loop: bool = True,
        back_solve_stop: bool = True,
    ) -> None:
        self.model, self.potential = owner.model, owner.potential
        self.barrier, self.friction = owner.barrier, owner.friction
        self.newton, self.linear_solver, self.dt = owner.newton, linear_solver, owner.dt
        self.take_last_increment = take_last_increment
        self.friction_loop, self.back_solve_stop = friction_loop, back_solve_stop
        # the phases every step reports (0 when a step has none: the same metrics columns)
        self.phases = TIMING_KEYS + ("friction",) * (self.friction is not None)
        self.phases += ("scripted_ccd",) * (self.barrier is not None)
        # kept across steps so an unchanged Hessian pattern is not rebuilt every step
        self._assembler: TripletAssembler | None = None
        #: over the minimisations of the last ``solve``: Newton systems solved only with the
        #: rounding-level diagonal shift (``NewtonResult.shifted_solves``) and its largest value
        self.shifted_solves, self.max_shift = 0, 0.0

    def solve(
        self,
        state: State,
        nodes: StepNodes,
        x_start: np.ndarray,
        x_hat: np.ndarray,
        predicted: np.ndarray | None,
        lag_at: np.ndarray | None = None,
    ) -> tuple[NewtonResult, int, bool]:
        """Solve with scripted nodes brought to their end-of-step positions without crossing.

        Scripted nodes are not unknowns, so CCD along Newton directions never sees their motion:
        a scripted body moving farther in a step than its gap would jump over particles. They
        are therefore moved from their start-of-step positions toward their targets as far as
        CCD allows (0.9 x the earliest impact), the step is re-solved there (the barrier pushes
        what is in the way), and so on until the targets are reached; the last solve, with every
        scripted node at its target, is the step's result. Where the unknowns held at x^n are
        in the way, they move along (``_carry``): held, every sub-step ends with the scripted
        body at a tenth of its gap (hertz example: 435 Newton iterations per step; carried, 52).
        The sub-steps before the last lag friction once instead of running the friction loop:
        they only start the next.

        Args:
            state: the state at t^n.
            nodes: the step's node fields; ``nodes.fixed`` is the array the terms read for
                scripted positions: it is set to each part-way position and left at the target.
            x_start: Newton's start ``(n_dof,)`` in m.
            x_hat: the inertial prediction ``(n_dof,)`` in m (BFEMP eq. 22).
            predicted: the predicted x^{n+1} ``(n_dof,)`` for a warm start, or None.
            lag_at: positions ``(n_dof,)`` in m where the last solve lags friction first (its
                start when None); ``two_stage`` lags at x^n.
        """
        model, pot, barrier = self.model, self.potential, self.barrier
        self.shifted_solves, self.max_shift = 0, 0.0
        target = nodes.fixed.copy()
        start = target.copy()
        n_fem = model.n_fem_nodes
        start[:n_fem][model.fem_prescribed] = state.fem_x[model.fem_prescribed]
        if nodes.mpm is not None:  # sticky nodes of moving level sets start where they are
            start[n_fem:] = nodes.mpm.stencils.active_x
        timings = dict.fromkeys(self.phases, 0.0)
        if barrier is None or np.array_equal(start, target):
            result, f_its, f_ok = self._friction_loop(
                self._warm_started(x_start, predicted),
                timings,
                loop=self.friction_loop,
                lag_at=lag_at,
            )
            result.timings = timings
            return result, f_its, f_ok
        fixed = nodes.fixed
        current, x = start, x_start
        carry = None  # the unknowns' move along with the scripted nodes; None: held
        its, friction_its, friction_ok = 0, 0, True
        for _ in range(self.SCRIPTED_SUBSTEPS):
            fixed[:] = current
            t0 = time.perf_counter()
            frac = self._fraction(x, carry, current, target)
            if frac < 1.0 and carry is None:  # held unknowns are in the way: carry them
                carry = self._carry(x_hat, x_start)
                frac = self._fraction(x, carry, current, target)
            add_timings(timings, {"scripted_ccd": time.perf_counter() - t0})
            if frac >= 1.0:
                x = x if carry is None else x + carry
                break
            current = current + frac * (target - current)
            if carry is not None:
                x, carry = x + frac * carry, (1.0 - frac) * carry
            fixed[:] = current
            result, f_its, f_ok = self._friction_loop(x, timings, loop=False)
            its += result.nit
            friction_its = max(friction_its, f_its)  # per solve, as capped
            friction_ok &= f_ok
            if not result.success:
                result.nit, result.timings = its, timings
                return result, friction_its, friction_ok
            x = pot.to_positions(result.x)
        else:
            fixed[:] = target
            raise StepError.failed(
                state.step + 1,
                state.t + self.dt,
                "SCRIPTED_MOTION_BLOCKED",
                f"scripted nodes could not reach their positions without crossing after "
                f"{self.SCRIPTED_SUBSTEPS} part-way moves (something is squeezed "
                f"between a scripted body and another boundary?)",
                iterations={"newton": its},
                timings=timings,
            )
        fixed[:] = target
        result, f_its, f_ok = self._friction_loop(
            x, timings, loop=self.friction_loop, lag_at=lag_at
        )
        result.nit += its
        result.timings = timings
        return result, max(friction_its, f_its), friction_ok and f_ok

    def _carry(self, x_hat: np.ndarray, x_start: np.ndarray) -> np.ndarray:
        """The move ``(n_dof,)`` in m of the unknowns while the scripted nodes go to their
        targets: x_hat - x^n (BFEMP eq. 22's inertial prediction: dt v^n under backward Euler), slip
        normal coordinates held. A predictor only: the solve ends where it ends."""
        pot = self.potential
        p = pot.to_unknowns(x_hat - x_start)
        if pot.fixed_dofs is not None:
            p[pot.fixed_dofs] = 0.0
        return pot.to_positions(p)

    def _fraction(
        self, x: np.ndarray, carry: np.ndarray | None, current: np.ndarray, target: np.ndarray
    ) -> float:
        """How far along (scripted nodes current -> target, unknowns x -> x + carry, held when
        None) the step may go: the barrier's CCD on the joint path, and no det F = 0 on the
        unknowns' part."""
        pot = self.potential
        pot.solution_changed(pot.to_unknowns(x))
        frac = self.barrier.scripted_step(x, current, target, None if carry is None else x + carry)
        if carry is not None and np.any(carry):
            others = (t for t in pot.terms if t is not self.barrier)
            frac = min(frac, *(t.max_step_size(x, carry) for t in others))
        return frac

    def _warm_started(self, x_n: np.ndarray, predicted: np.ndarray | None) -> np.ndarray:
        """Newton's start: x^n moved toward a predicted x^{n+1} ``(n_dof,)`` in m.

        The prediction (BFEMP eq. 21 with a^{n+1} = a^n; slip-normal coordinates stay fixed) is
        taken only when no contact pair is active at x^n, the whole move passes the line search's
        feasibility filter (no contact or det F = 0 before 1 / 0.9 of it, section 5) and it
        lowers E; otherwise Newton starts at x^n. Off by default: no gain measured on the rings
        and cantilever demos (design note ``measurements``, barrier).
        """
        pot, barrier = self.potential, self.barrier
        if predicted is None or x_n.size == 0:
            return x_n
        y_n = pot.to_unknowns(x_n)
        p = pot.to_unknowns(predicted - x_n)
        if pot.fixed_dofs is not None:
            p[pot.fixed_dofs] = 0.0
        if not np.any(p):
            return x_n
        pot.solution_changed(y_n)
        in_contact = barrier is not None and barrier.pairs.n_pairs > 0
        if in_contact or pot.max_step_size(y_n, p) < 1.0:
            return x_n
        e_n = pot.value(y_n)
        y = y_n + p
        pot.solution_changed(y)
        e = pot.value(y)
        if not (np.isfinite(e) and e < e_n):
            pot.solution_changed(y_n)
            return x_n
        return pot.to_positions(y)

    def _friction_loop(
        self,
        x_n: np.ndarray,
        timings: dict[str, float],
        *,
        loop: bool = True,
        lag_at: np.ndarray | None = None,
    ) -> tuple[NewtonResult, int, bool]:
        """Minimise; with friction, the outer lagged-friction loop of Algorithm 1.

        The loop ends when a minimisation under freshly lagged friction data needs no Newton
        step (its first increment is already below the tolerance), or at the cap, or earlier
        when it stalls (``stalled``: its re-solves stop shrinking), which is reported
        (``friction_converged = False`` and the step's ``FRICTION_LOOP`` note), not silent.
        ``loop=False``: friction lagged once at ``x_n`` (or ``lag_at``), one minimisation (a
        scripted sub-step before the last, or ``two_stage``'s semi-implicit friction). The first
        lag is at ``lag_at`` (positions ``(n_dof,)`` in m) when given, else at ``x_n``. The result
        carries the Newton iterations of all the loop's minimisations; their phase seconds are
        added to ``timings``.
        """
        pot, friction = self.potential, self.friction
        y = pot.to_unknowns(x_n)
        if friction is None:
            return self._minimize(y, timings), 0, True
        cap = self.model.contact.friction_iterations if loop else 1
        total_it, result = 0, None  # result: set by the first minimisation (j = 0)
        moves: list[float] = []  # how far each re-solve (j >= 1) moved the unknowns, in m
        for j in range(cap):
            t0 = time.perf_counter()
            friction.lag(lag_at if j == 0 and lag_at is not None else pot.to_positions(y))
            p = self._increment_below_tol(y, result) if j > 0 and self.back_solve_stop else None
            add_timings(timings, {"friction": time.perf_counter() - t0})
            if p is not None:
                result.nit, result.x = total_it, self._take(y, p)
                return result, j + 1, True
            result = self._minimize(y, timings)
            total_it += result.nit
            if not result.success:
                result.nit = total_it
                return result, j + 1, False
            if j > 0 and result.nit == 0:  # its factorisation is of the fresh data: exact p
                p = self._increment_below_tol(y)
                result.nit = total_it
                result.x = y if p is None else self._take(y, p)
                return result, j + 1, True
            if j > 0:
                moves.append(pot.increment_norm(result.x - y))
                if j + 1 < cap and stalled(moves, self.STALL_WINDOW, self.STALL_FACTOR):
                    log.info(  # the user sees the step's FRICTION_LOOP note
                        "friction loop stalled after %d iterations: its last %d re-solves moved "
                        "the unknowns by %s m, none below %g x the least move before them "
                        "(%.3e m); stopped before the cap of %d, unconverged",
                        j + 1,
                        self.STALL_WINDOW,
                        ", ".join(f"{m:.2e}" for m in moves[-self.STALL_WINDOW :]),
                        self.STALL_FACTOR,
                        min(moves[: -self.STALL_WINDOW]),
                        cap,
                    )
                    result.nit = total_it
                    return result, j + 1, False
            y = result.x
        result.nit = total_it
        if not loop:
            return result, 1, True
        log.info("friction loop did not converge in %d iterations", cap)  # FRICTION_LOOP note
        return result, cap, False

    def _minimize(self, y: np.ndarray, timings: dict[str, float]) -> NewtonResult:
        """One projected Newton solve from ``y``; its phase seconds add to ``timings``."""
        fixed = self.potential.fixed_dofs
        free = None if fixed is None or not fixed.any() else ~fixed
        if self._assembler is None or not self._assembler.fits(y.size, free):
            self._assembler = TripletAssembler(y.size, free=free)
        result = minimize(
            self.potential,
            y,
            options=self.newton,
            linear_solver=self.linear_solver,
            assembler=self._assembler,
        )
        add_timings(timings, result.timings)
        self.shifted_solves += result.shifted_solves
        self.max_shift = max(self.max_shift, result.max_shift)
        return result

    def rounding_notes(self) -> list[str]:
        """The named note of the last ``solve`` when a Newton system needed the rounding shift
        (``PSD_ROUNDING_SHIFT``, :func:`solvers.linear.rounding_shift`), else none."""
        if not self.shifted_solves:
            return []
        return [
            f"PSD_ROUNDING_SHIFT: {self.shifted_solves} projected Newton system(s) were "
            f"indefinite by floating-point rounding (a barrier block near d = 0) and were solved "
            f"with a rounding-level diagonal shift (at most {self.max_shift:.3e})"
        ]

    def _increment_below_tol(
        self, y: np.ndarray, result: NewtonResult | None = None
    ) -> np.ndarray | None:
        """The friction loop's stopping test, by a back-solve instead of a factorisation.

        Algorithm 1 stops when the Newton increment under friction data refreshed at y is below
        the tolerance (||p||_inf / dt, section 5). p is computed with the last factorisation
        (the Hessian at y before the refresh: the friction blocks lag by one update) and the
        fresh gradient; a cheap test that only decides when to stop: when it says no (None),
        Newton runs. On success it returns p ``(n,)`` and stores the gradient in ``result.jac``
        (boundary reactions use it) when a ``result`` is given; without one it is the last
        increment of a solve that needed no Newton step. None too when the solver cannot
        back-solve.
        """
        solve_again = getattr(self.linear_solver, "solve_again", None)
        if solve_again is None:
            return None
        pot = self.potential
        pot.solution_changed(y)
        grad = pot.gradient(y)  # (n,) in N
        free = None if pot.fixed_dofs is None else ~pot.fixed_dofs
        p_free = solve_again(-(grad if free is None else grad[free]))
        if p_free is None:
            return None
        p = p_free if free is None else np.zeros(grad.size)
        if free is not None:
            p[free] = p_free
        if not pot.increment_norm(p) < self.newton.tol * self.dt:
            return None
        if result is not None:
            result.jac = grad
        return p

    def _take(self, y: np.ndarray, p: np.ndarray) -> np.ndarray:
        """y + alpha p with the freshly lagged friction's last increment p (below tolerance),
        alpha = min(1, 0.9 x the first impact or det F = 0 along p): the step ends at the
        solution of the friction data it stopped on.

        Why it is taken: the step's velocity is v^{n+1} = (x^{n+1} - x^n) / dt under backward
        Euler (``Integrator.acceleration``), so a position left at the previous lag's solution
        carries that lag's friction error into the velocity every step, always in the same
        direction. With velocities from the forces (the paper's Algorithm 2) it is not taken (y
        is returned): there it made the slope benchmark worse (design note ``measurements``,
        barrier).
        """
        if not self.take_last_increment:
            return y
        pot = self.potential
        pot.solution_changed(y)
        alpha = min(1.0, pot.max_step_size(y, p))
        return y + alpha * p


def stalled(moves: list[float], window: int, factor: float) -> bool:
    """Whether a lagged-friction loop has stalled: its last ``window`` re-solves each moved the
    unknowns by more than ``factor`` x the least move of the re-solves before them.

    ``moves``: the increment norm (m) of every re-solve so far, in order. The loop is a
    fixed-point iteration on the lagged normal forces and tangent bases (Algorithm 1): ``window``
    moves with no ``factor`` reduction mean a contraction rate above factor^(1/window) (0.79 for
    3 and 0.5), more than 50 re-lags from 0.1 m to 1e-6 m, past the default cap of 20 (design
    note ``measurements``, barrier).
    """
    if len(moves) <= window:
        return False
    return min(moves[-window:]) > factor * min(moves[:-window])
