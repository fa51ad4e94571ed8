"""The minimisation of one ``barrier`` step: scripted nodes, warm start, the friction loop.

``ScriptedSolve.solve`` brings scripted nodes to their end-of-step positions without crossing
(part-way moves filtered by CCD), optionally warm-starts Newton from a prediction, and runs the
outer lagged-friction loop of Algorithm 1 around ``solvers.newton.minimize``. Everything a solve
needs is passed in; what it returns is the Newton result with the iterations and per-phase timings
of every minimisation of the step summed, the lagged-friction updates of the step (summed over its
solves; each solve caps them at ``contact.friction_iterations``) and whether every friction loop
converged.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping

import numpy as np

from bfemp.contact.friction import FrictionTerm
from bfemp.contact.term import BarrierTerm
from bfemp.model import Model
from bfemp.potential import IncrementalPotential
from bfemp.state import State
from bfemp.steppers._scaffold import StepNodes
from bfemp.steppers.base import StepError, StepReport
from solvers.linear import LinearSolver
from solvers.newton import minimize
from solvers.options import NewtonOptions
from solvers.result import NewtonResult

__all__ = ["ScriptedSolve", "add_timings"]

log = logging.getLogger(__name__)


def add_timings(total: dict[str, float], more: Mapping[str, float]) -> dict[str, float]:
    """``total`` with ``more``'s seconds added per phase (in place; returned)."""
    for key, seconds in more.items():
        total[key] = total.get(key, 0.0) + float(seconds)
    return total


class ScriptedSolve:
    """The minimisation of a ``barrier`` step (see the module docstring); keeps no state.

    Args:
        model: the static model.
        potential: the step's incremental potential (begun for the step by the caller).
        barrier: its barrier term, or None.
        friction: its friction term, or None.
        newton: Newton options (``step_scale`` = dt).
        linear_solver: the linear solver.
        dt: the time step in s.
    """

    #: cap of the part-way moves of scripted nodes within one step
    SCRIPTED_SUBSTEPS = 64

    def __init__(
        self,
        model: Model,
        potential: IncrementalPotential,
        barrier: BarrierTerm | None,
        friction: FrictionTerm | None,
        newton: NewtonOptions,
        linear_solver: LinearSolver,
        dt: float,
    ) -> None:
        self.model, self.potential, self.barrier, self.friction = (
            model,
            potential,
            barrier,
            friction,
        )
        self.newton, self.linear_solver, self.dt = newton, linear_solver, dt

    def solve(
        self,
        state: State,
        nodes: StepNodes,
        x_start: np.ndarray,
        predicted: np.ndarray | None,
    ) -> tuple[NewtonResult, int, bool]:
        """Solve with scripted nodes brought to their end-of-step positions without crossing.

        Scripted nodes are not unknowns, so CCD along Newton directions never sees their motion:
        a scripted body moving farther in a step than its gap would jump over particles. They
        are therefore moved from their start-of-step positions toward their targets as far as
        CCD allows (0.9 x the earliest impact, the unknowns held), the step is re-solved there
        (the barrier pushes what is in the way), and so on until the targets are reached; the
        last solve, with every scripted node at its target, is the step's result.

        Args:
            state: the state at t^n.
            nodes: the step's node fields; ``nodes.fixed`` is the array the terms read for
                scripted positions: it is set to each part-way position and left at the target.
            x_start: Newton's start ``(n_dof,)`` in m.
            predicted: the predicted x^{n+1} ``(n_dof,)`` for a warm start, or None.
        """
        model, pot, barrier = self.model, self.potential, self.barrier
        target = nodes.fixed.copy()
        start = target.copy()
        n_fem = model.n_fem_nodes
        start[:n_fem][model.fem_prescribed] = state.fem_x[model.fem_prescribed]
        if nodes.mpm is not None:  # sticky nodes of moving level sets start where they are
            start[n_fem:] = nodes.mpm.stencils.active_x
        if barrier is None or np.array_equal(start, target):
            return self._friction_loop(self._warm_started(x_start, predicted))
        fixed = nodes.fixed
        current, x = start, x_start
        its, friction_its, friction_ok, timings = 0, 0, True, {}
        for _ in range(self.SCRIPTED_SUBSTEPS):
            fixed[:] = current
            pot.solution_changed(pot.to_unknowns(x))
            frac = barrier.scripted_step(x, current, target)
            if frac >= 1.0:
                break
            current = current + frac * (target - current)
            fixed[:] = current
            result, f_its, f_ok = self._friction_loop(x)
            its += result.nit
            friction_its += f_its
            friction_ok &= f_ok
            add_timings(timings, result.timings)
            if not result.success:
                result.nit, result.timings = its, timings
                return result, friction_its, friction_ok
            x = pot.to_positions(result.x)
        else:
            fixed[:] = target
            raise StepError(
                StepReport(
                    step=state.step + 1,
                    t=state.t + self.dt,
                    success=False,
                    status="SCRIPTED_MOTION_BLOCKED",
                    message=(
                        f"scripted nodes could not reach their positions without crossing after "
                        f"{self.SCRIPTED_SUBSTEPS} part-way moves (something is squeezed "
                        f"between a scripted body and another boundary?)"
                    ),
                    iterations={"newton": its},
                    timings=timings,
                )
            )
        fixed[:] = target
        result, f_its, f_ok = self._friction_loop(x)
        result.nit += its
        result.timings = add_timings(timings, result.timings)
        return result, friction_its + f_its, friction_ok and f_ok

    def _warm_started(self, x_n: np.ndarray, predicted: np.ndarray | None) -> np.ndarray:
        """Newton's start: x^n moved toward a predicted x^{n+1} ``(n_dof,)`` in m.

        The prediction (eq. 21 with a^{n+1} = a^n; slip-normal coordinates stay fixed) is taken
        only when no contact pair is active at x^n, the whole move passes the line search's
        feasibility filter (no contact or det F = 0 before 1 / 0.9 of it, section 5) and it
        lowers E; otherwise Newton starts at x^n. Measured (hence off by default): rings demo to
        t = 0.1 s, 390 Newton iterations against 386 from x^n (free-flight steps far from
        contact need 0 instead of 1, but steps where contact was lost at x^n need more; taken in
        contact too, cut short at the filter, it cost 23 % more, as the prediction ignores the
        contact forces); cantilever demo, 2 per step either way (the prediction is not within
        the 1e-6 m/s tolerance).
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

    def _friction_loop(self, x_n: np.ndarray) -> tuple[NewtonResult, int, bool]:
        """Minimise; with friction, the outer lagged-friction loop of Algorithm 1.

        The loop ends when a minimisation under freshly lagged friction data needs no Newton
        step (its first increment is already below the tolerance), or at the cap, which is
        reported (``friction_converged = False``), not silent. The result carries the Newton
        iterations and timings of all the loop's minimisations.
        """
        pot, friction = self.potential, self.friction
        y = pot.to_unknowns(x_n)
        if friction is None:
            result = minimize(pot, y, options=self.newton, linear_solver=self.linear_solver)
            return result, 0, True
        cap = self.model.contact.friction_iterations
        total_it, timings = 0, {}
        for j in range(cap):
            friction.lag(pot.to_positions(y))
            if j > 0 and self._increment_below_tol(y, result):
                result.nit, result.timings = total_it, timings
                return result, j + 1, True
            result = minimize(pot, y, options=self.newton, linear_solver=self.linear_solver)
            total_it += result.nit
            add_timings(timings, result.timings)
            if not result.success:
                result.nit, result.timings = total_it, timings
                return result, j + 1, False
            if j > 0 and result.nit == 0:
                result.nit, result.timings = total_it, timings
                return result, j + 1, True
            y = result.x
        result.nit, result.timings = total_it, timings
        log.warning("friction loop did not converge in %d iterations", cap)
        return result, cap, False

    def _increment_below_tol(self, y: np.ndarray, result: NewtonResult) -> bool:
        """The friction loop's stopping test, by a back-solve instead of a factorisation.

        Algorithm 1 stops when the Newton increment under friction data refreshed at y is below
        the tolerance (||p||_inf / dt, section 5). p is computed with the last factorisation
        (the Hessian at y before the refresh: the friction blocks lag by one update) and the
        fresh gradient; a cheap test that only decides when to stop: when it says no, Newton
        runs. On success the gradient is stored in ``result.jac`` (boundary reactions use it).
        """
        solve_again = getattr(self.linear_solver, "solve_again", None)
        if solve_again is None:
            return False
        pot = self.potential
        pot.solution_changed(y)
        grad = pot.gradient(y)
        free = None if pot.fixed_dofs is None else ~pot.fixed_dofs
        p_free = solve_again(-(grad if free is None else grad[free]))
        if p_free is None:
            return False
        p = p_free if free is None else np.zeros(grad.size)
        if free is not None:
            p[free] = p_free
        if not pot.increment_norm(p) < self.newton.tol * self.dt:
            return False
        result.jac = grad
        return True
