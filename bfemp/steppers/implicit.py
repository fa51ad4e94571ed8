"""BFEMP's implicit step (Algorithm 1 without MPM transfers and contact, which later plug in here).

One step: predict x_hat (eq. 21-22), minimise the incremental potential with projected Newton
(Algorithm 2) from x^n, then a^{n+1} = -M^-1 dPsi/dx(x^{n+1}) and the Newmark velocity update
(Algorithm 2, line 14). Prescribed nodes follow their motion and are not unknowns.
"""

from __future__ import annotations

import logging
import time
from dataclasses import replace

import numpy as np

from bfemp.dofs import DofLayout
from bfemp.integrators import Integrator
from bfemp.model import Model
from bfemp.potential import IncrementalPotential
from bfemp.state import State
from bfemp.steppers.base import StepError, StepReport
from bfemp.terms import (
    ElasticityTerm,
    ExternalForceTerm,
    GravityTerm,
    InertiaTerm,
    StepContext,
    fem_cell_stencils,
)
from solvers.linear import LinearSolver, default_linear_solver
from solvers.newton import minimize
from solvers.options import NewtonOptions
from solvers.result import NewtonResult, NewtonStatus

__all__ = ["ImplicitStepper"]

log = logging.getLogger(__name__)


def build_potential(model: Model) -> IncrementalPotential:
    """The terms this model needs, and nothing else (a scene pays only for what it has)."""
    potentials = []
    body_law = [body.material.law for body in model.fem_bodies]
    laws = {id(law): law for law in body_law}
    for law in laws.values():
        bodies = [b.index for b in model.fem_bodies if b.material.law is law]
        mask = np.isin(model.fem_cell_body, bodies)
        stencils = fem_cell_stencils(model, mask)
        potentials.append(ElasticityTerm(law, stencils, name=f"elasticity[{law.name}]"))
    if model.has_gravity:
        potentials.append(GravityTerm(model.gravity))
    if model.has_load:
        potentials.append(ExternalForceTerm(model.fem_load))
    return IncrementalPotential(InertiaTerm(), potentials)


class ImplicitStepper:
    """The ``"barrier"`` strategy: one incremental-potential minimisation per step.

    Args:
        model: the static model.
        integrator: Newmark-family parameters.
        dt: time step in s.
        newton: Newton options (``step_scale`` is set to ``dt``: tolerance in m/s).
        linear_solver: defaults to CHOLMOD (scipy fallback with a warning).
    """

    def __init__(
        self,
        model: Model,
        *,
        integrator: Integrator,
        dt: float,
        newton: NewtonOptions,
        linear_solver: LinearSolver | None = None,
    ) -> None:
        self.model = model
        self.integrator = integrator
        self.dt = float(dt)
        self.newton = replace(newton, step_scale=self.dt)
        self.linear_solver = linear_solver if linear_solver is not None else default_linear_solver()
        self.potential = build_potential(model)
        self.layout = DofLayout(model.dim, ~model.fem_prescribed, model.n_fem_nodes)
        self.dof_mass = np.repeat(model.fem_mass[self.layout.free_nodes], model.dim)

    @property
    def terms(self) -> list[str]:
        """Names of the active energy terms."""
        return [term.name for term in self.potential.terms]

    def _context(self, state: State, t_next: float, x_hat: np.ndarray) -> StepContext:
        return StepContext(
            model=self.model,
            state=state,
            dt=self.dt,
            layout=self.layout,
            fixed_positions=self.model.prescribed_positions(t_next),
            x_hat=x_hat,
            dof_mass=self.dof_mass,
        )

    def accelerations(self, state: State) -> np.ndarray:
        """a = -M^-1 dPsi/dx at ``state`` for the free nodes, as ``(N, d)`` (zero elsewhere)."""
        x = self.layout.restrict(state.fem_x)
        self.potential.begin_step(self._context(state, state.t, x), self.integrator.weight(self.dt))
        self.potential.solution_changed(x)
        return self.layout.expand(-self.potential.potential_gradient(x) / self.dof_mass)

    def initialize(self, state: State) -> State:
        """Set a^0 consistently with the forces at t = 0 when the integrator uses it."""
        out = state.copy()
        if self.integrator.uses_acceleration:
            out.fem_a = self.accelerations(state)
        return out

    def step(self, state: State) -> tuple[State, StepReport]:
        """Advance ``state`` by ``dt``; raises ``StepError`` when Newton fails."""
        started = time.perf_counter()
        dt, layout, integ = self.dt, self.layout, self.integrator
        t_next = state.t + dt
        x_n = layout.restrict(state.fem_x)
        v_n = layout.restrict(state.fem_v)
        a_n = layout.restrict(state.fem_a)
        x_hat = integ.predict(x_n, v_n, a_n, dt)
        ctx = self._context(state, t_next, x_hat)
        self.potential.begin_step(ctx, integ.weight(dt))
        if layout.n_dof == 0:  # every node scripted: nothing to solve
            result = NewtonResult(
                x=x_n,
                success=True,
                status=NewtonStatus.CONVERGED,
                message="no unknowns",
                step_inf_norm=0.0,
            )
        else:
            result = minimize(
                self.potential, x_n.copy(), options=self.newton, linear_solver=self.linear_solver
            )
        report_args = dict(
            step=state.step + 1,
            t=t_next,
            success=bool(result.success),
            status=result.status.name,
            message=result.message,
            newton_iterations=int(result.nit),
            residual=float(result.step_inf_norm) / dt,
        )
        if not result.success:
            raise StepError(StepReport(**report_args, timings=dict(result.timings)))
        x_next = result.x
        # a^{n+1} from the forces at x^{n+1} (Algorithm 2, line 14), then eq. 21 for v.
        self.potential.solution_changed(x_next)
        a_next = -self.potential.potential_gradient(x_next) / self.dof_mass
        v_next = integ.velocity(v_n, a_n, a_next, dt)

        new = state.copy()
        new.t = t_next
        new.step = state.step + 1
        new.fem_x = ctx.fixed_positions.copy()
        new.fem_x[layout.free_nodes] = x_next.reshape(-1, self.model.dim)
        prescribed = self.model.fem_prescribed
        v_scripted = self.model.prescribed_velocities(t_next)
        new.fem_v = v_scripted
        new.fem_v[layout.free_nodes] = v_next.reshape(-1, self.model.dim)
        new.fem_a = np.zeros_like(state.fem_a)
        new.fem_a[prescribed] = (v_scripted[prescribed] - state.fem_v[prescribed]) / dt
        new.fem_a[layout.free_nodes] = a_next.reshape(-1, self.model.dim)
        timings = dict(result.timings)
        timings["step"] = time.perf_counter() - started
        report = StepReport(**report_args, timings=timings)
        log.debug("step %d: %d Newton iterations", report.step, report.newton_iterations)
        return new, report
