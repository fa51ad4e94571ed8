"""BFEMP's implicit step (Algorithm 1; contact plugs into the same potential).

One step:
1. MPM: quadratic B-spline stencils at x_p^n and P2G of mass, velocity (and acceleration for
   Newmark) per Tables 1-3 (line 2); level-set constraints of the active grid nodes.
2. Unknowns: free FEM nodes and unconstrained grid nodes, prescribed FEM nodes follow their motion,
   sticky grid nodes stay, slip grid nodes move tangentially only (rotated frames).
3. Predict x_hat (eqs. 21-22), minimise the incremental potential with projected Newton from x^n
   (Algorithm 2), then a^{n+1} = -M^-1 dPsi/dx(x^{n+1}) and the velocity update of eq. 21
   (Algorithm 2, line 14); constrained components get zero velocity and acceleration. Under an
   integrator with ``implicit_contact`` the contact forces are kept out of a^{n+1} and added to
   the velocity as an impulse (``bfemp.integrators``).
4. MPM: G2P of positions, velocities, F (and APIC C, Newmark a) per Tables 1-3 (line 12).
"""

from __future__ import annotations

import logging
import time
from dataclasses import replace

import numpy as np

from bfemp.contact.adaptive import AdaptiveKappa
from bfemp.contact.friction import FrictionTerm
from bfemp.contact.intersection import step_intersection
from bfemp.contact.term import BarrierTerm
from bfemp.dofs import DofLayout
from bfemp.frames import NodeFrames
from bfemp.integrators import Integrator
from bfemp.model import Model
from bfemp.mpm.boundaries import normal_frames
from bfemp.mpm.elasticity import MpmElasticityTerm
from bfemp.mpm.step import MpmStep, prepare_mpm_step
from bfemp.mpm.transfer import grid_to_particles
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

__all__ = ["ImplicitStepper", "build_potential"]

log = logging.getLogger(__name__)


def _laws(bodies: tuple) -> dict[int, object]:
    return {id(b.material.law): b.material.law for b in bodies}


def build_potential(model: Model) -> IncrementalPotential:
    """The terms this model needs, and nothing else (a scene pays only for what it has)."""
    potentials = []
    # cells whose every node is scripted add nothing to the minimisation: no stencil for them
    moving = ~np.all(model.fem_prescribed[model.fem_cells], axis=1)
    for law in _laws(model.fem_bodies).values():
        bodies = [b.index for b in model.fem_bodies if b.material.law is law]
        mask = np.isin(model.fem_cell_body, bodies) & moving
        if not mask.any():
            continue
        stencils = fem_cell_stencils(model, mask)
        potentials.append(ElasticityTerm(law, stencils, name=f"elasticity[{law.name}]"))
    for law in _laws(model.mpm_bodies).values():
        bodies = [b for b in model.mpm_bodies if b.material.law is law]
        particles = np.concatenate([np.arange(b.particles.start, b.particles.stop) for b in bodies])
        owner = model.mpm_particle_body[particles]
        mu = np.array([b.material.mu for b in model.mpm_bodies])[owner]
        lam = np.array([b.material.lam for b in model.mpm_bodies])[owner]
        potentials.append(
            MpmElasticityTerm(law, particles, mu, lam, name=f"mpm_elasticity[{law.name}]")
        )
    if model.has_gravity:
        potentials.append(GravityTerm(model.gravity))
    if model.has_load:
        potentials.append(ExternalForceTerm(model.fem_load))
    if has_contact(model):
        c = model.contact
        barrier = BarrierTerm(c.dhat, 1.0 if c.adaptive_kappa else c.kappa)
        potentials.append(barrier)
        if c.has_friction:
            potentials.append(FrictionTerm(c.mu, c.eps_v, barrier))
    return IncrementalPotential(InertiaTerm(), potentials)


def has_contact(model: Model) -> bool:
    """Contact is on and some pair can exist: FEM facets against particles or another FEM body."""
    if model.contact is None or not model.fem_bodies:
        return False
    return model.n_particles > 0 or len(model.fem_bodies) > 1


class ImplicitStepper:
    """The ``"barrier"`` strategy: one incremental-potential minimisation per step.

    Args:
        model: the static model.
        integrator: Newmark-family parameters.
        dt: time step in s.
        newton: Newton options (``step_scale`` is set to ``dt``: tolerance in m/s).
        linear_solver: defaults to CHOLMOD (scipy fallback with a warning).
        transfer: MPM particle-grid transfer, ``"apic"``, ``"pic"`` or ``"flip"``.
        warm_start: start Newton from the predicted x^{n+1} (see ``_warm_started``) instead of
            from x^n.
    """

    def __init__(
        self,
        model: Model,
        *,
        integrator: Integrator,
        dt: float,
        newton: NewtonOptions,
        linear_solver: LinearSolver | None = None,
        transfer: str = "apic",
        warm_start: bool = False,
    ) -> None:
        self.model = model
        self.warm_start = bool(warm_start)
        self.integrator = integrator
        self.dt = float(dt)
        self.newton = replace(newton, step_scale=self.dt)
        self.linear_solver = linear_solver if linear_solver is not None else default_linear_solver()
        self.transfer = transfer
        self.potential = build_potential(model)
        self._fem_layout = DofLayout(model.dim, ~model.fem_prescribed, model.n_fem_nodes)
        self.layout = self._fem_layout
        self.barrier = next(
            (t for t in self.potential.potentials if isinstance(t, BarrierTerm)), None
        )
        self.friction = next(
            (t for t in self.potential.potentials if isinstance(t, FrictionTerm)), None
        )
        self.adaptive: AdaptiveKappa | None = None

    def _adapt_kappa(self, ctx: StepContext, x_n: np.ndarray) -> None:
        """kappa = "auto": bounds on the first step, gradient balance when contact appears."""
        contact = self.model.contact
        if self.barrier is None or not contact.adaptive_kappa:
            return
        if self.adaptive is None:
            moduli = [b.material.E for b in (*self.model.fem_bodies, *self.model.mpm_bodies)]
            omega = self.barrier.collisions.omega
            self.adaptive = AdaptiveKappa.for_scene(moduli, omega, contact.dhat, self.model.dim)
        if not self.adaptive.initialised:
            self.barrier.kappa = 1.0
            self.potential.solution_changed(self.potential.to_unknowns(x_n))
            if self.barrier.pairs.n_pairs:
                weight = self.integrator.weight(self.dt)
                g_barrier = self.barrier.gradient(x_n)
                g_all = self.potential.inertia.gradient(x_n) + weight * (
                    self.potential.potential_gradient(x_n) - g_barrier
                )
                self.adaptive.initialise(g_all, g_barrier, self.integrator.contact_weight(self.dt))
        self.barrier.kappa = self.adaptive.kappa

    @property
    def terms(self) -> list[str]:
        """Names of the active energy terms."""
        return [term.name for term in self.potential.terms]

    # ------------------------------------------------------------------ step set-up
    def _setup(
        self, state: State, t_next: float
    ) -> tuple[StepContext, MpmStep | None, np.ndarray, np.ndarray, np.ndarray, NodeFrames | None]:
        """Layout, context and the all-node x^n, v^n, a^n of a step from ``state`` to t_next.

        ``self.x_start`` is the solver's start: x^n, with nodes on moving slip boundaries moved
        along with them (their normal coordinate is fixed there).
        """
        model, d = self.model, self.model.dim
        fem_fixed = model.prescribed_positions(t_next)
        if model.n_particles == 0:
            layout, mpm = self._fem_layout, None
            x_all, v_all, a_all = state.fem_x, state.fem_v, state.fem_a
            mass_all, fixed = model.fem_mass, fem_fixed
        else:
            mpm = prepare_mpm_step(
                model,
                state,
                self.transfer,
                with_acceleration=self.integrator.uses_acceleration,
                dt=t_next - state.t,
            )
            grid_x = mpm.stencils.active_x
            fields = mpm.fields
            grid_a = mpm.acceleration if mpm.acceleration is not None else 0.0 * grid_x
            free = np.concatenate([~model.fem_prescribed, ~mpm.constraints.sticky])
            layout = DofLayout(d, free, model.n_fem_nodes)
            x_all = np.concatenate([state.fem_x, grid_x])
            v_all = np.concatenate([state.fem_v, fields.velocity])
            a_all = np.concatenate([state.fem_a, grid_a])
            mass_all = np.concatenate([model.fem_mass, fields.mass])
            fixed = np.concatenate([fem_fixed, grid_x + mpm.constraints.shift])
        self.layout = layout
        x_n, v_n, a_n = layout.restrict(x_all), layout.restrict(v_all), layout.restrict(a_all)
        self.x_start = x_n
        if mpm is not None and mpm.constraints.shift.any():
            shift = np.concatenate([np.zeros((model.n_fem_nodes, d)), mpm.constraints.shift])
            self.x_start = x_n + layout.restrict(shift)
        ctx = StepContext(
            model=model,
            state=state,
            dt=self.dt,
            layout=layout,
            fixed_positions=fixed,
            x_hat=self.integrator.predict(x_n, v_n, a_n, self.dt),
            dof_mass=np.repeat(mass_all[layout.free_nodes], d),
            mpm=mpm,
        )
        if self.friction is not None:
            ctx.sliding = self._sliding_map(layout, x_all, v_all, a_all, fixed, t_next, mpm)
        frames = None
        if mpm is not None and mpm.constraints.slip.any():
            slip_nodes = np.flatnonzero(mpm.constraints.slip)
            dof_nodes = layout.dof_node[slip_nodes + mpm.node_offset]
            keep = dof_nodes >= 0
            frames = NodeFrames(
                d,
                layout.n_dof,
                dof_nodes[keep],
                normal_frames(mpm.constraints.normals[slip_nodes[keep]]),
            )
        return ctx, mpm, x_n, v_n, a_n, frames

    def _boundary_forces(
        self, result: NewtonResult, frames: NodeFrames, mpm: MpmStep, layout: DofLayout
    ) -> tuple[tuple[float, ...], ...]:
        """Reaction force (d,) in N of each level-set boundary on the body, from slip nodes.

        At the constrained optimum dE/dy_n = h^2 f_n for a fixed normal coordinate y_n: f_n is the
        force the boundary exerts along its normal (positive pushes the body away, negative pulls
        it: adhesion). Sticky nodes are not unknowns and are not included.
        """
        d = self.model.dim
        out = np.zeros((len(self.model.boundaries), d))
        if result.jac is None:
            return tuple(tuple(row) for row in out)
        weight = self.integrator.weight(self.dt)
        f_n = np.asarray(result.jac)[frames.normal_dofs()] / weight
        normals = frames.frames[:, :, 0]
        grid_nodes = layout.free_nodes[frames.nodes] - mpm.node_offset
        owner = mpm.constraints.owner[grid_nodes]
        np.add.at(out, owner, f_n[:, None] * normals)
        return tuple(tuple(float(c) for c in row) for row in out)

    def _sliding_map(
        self,
        layout: DofLayout,
        x_all: np.ndarray,
        v_all: np.ndarray,
        a_all: np.ndarray,
        fixed: np.ndarray,
        t_next: float,
        mpm: MpmStep | None,
    ) -> tuple[float, np.ndarray]:
        """U = s y + c: each node's sliding dt v^{n+1} over the step, affine in its position y.

        Free nodes: dt v^n + dt^2 ((1 - gamma) a^n + gamma a^{n+1}) with a^{n+1} = (y - x_hat) /
        (2 alpha beta dt^2) (eq. 21), so s = gamma / (2 alpha beta); scripted nodes: dt times
        their scripted velocity (sticky grid nodes: 0).
        """
        integ, dt = self.integrator, self.dt
        s = integ.gamma / (2.0 * integ.alpha * integ.beta)
        x_hat = integ.predict(x_all, v_all, a_all, dt)
        c = dt * v_all + dt * dt * (1.0 - integ.gamma) * a_all - s * x_hat
        v_end = np.zeros_like(x_all)
        n_fem = self.model.n_fem_nodes
        v_end[:n_fem] = self.model.prescribed_velocities(t_next)
        scripted = layout.dof_node < 0
        c[scripted] = dt * v_end[scripted] - s * fixed[scripted]
        return s, c

    #: cap of the part-way moves of scripted nodes within one step
    SCRIPTED_SUBSTEPS = 64

    def _solve_scripted(
        self, ctx: StepContext, state: State, mpm: MpmStep | None
    ) -> tuple[NewtonResult, int, bool]:
        """Solve with scripted nodes brought to their end-of-step positions without crossing.

        Scripted nodes are not unknowns, so CCD along Newton directions never sees their motion:
        a scripted body moving farther in a step than its gap would jump over particles. They
        are therefore moved from their start-of-step positions toward their targets as far as
        CCD allows (0.9 x the earliest impact, the unknowns held), the step is re-solved there
        (the barrier pushes what is in the way), and so on until the targets are reached; the
        last solve, with every scripted node at its target, is the step's result.
        """
        target = ctx.fixed_positions.copy()
        start = target.copy()
        n_fem = self.model.n_fem_nodes
        start[:n_fem][self.model.fem_prescribed] = state.fem_x[self.model.fem_prescribed]
        if mpm is not None:  # sticky nodes of moving level sets start where they are
            start[n_fem:] = mpm.stencils.active_x
        if self.barrier is None or np.array_equal(start, target):
            return self._solve(self._warm_started(self.x_start, self._predicted))
        fixed = ctx.fixed_positions  # the terms read this array: it is updated in place
        current = start
        x = self.x_start
        its, friction_its, friction_ok = 0, 0, True
        for _ in range(self.SCRIPTED_SUBSTEPS):
            fixed[:] = current
            self.potential.solution_changed(self.potential.to_unknowns(x))
            frac = self.barrier.scripted_step(x, current, target)
            if frac >= 1.0:
                break
            current = current + frac * (target - current)
            fixed[:] = current
            result, f_its, f_ok = self._solve(x)
            its += result.nit
            friction_its += f_its
            friction_ok &= f_ok
            if not result.success:
                return result, friction_its, friction_ok
            x = self.potential.to_positions(result.x)
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
                    newton_iterations=its,
                    residual=float("nan"),
                )
            )
        fixed[:] = target
        result, f_its, f_ok = self._solve(x)
        result.nit += its
        return result, friction_its + f_its, friction_ok and f_ok

    def _warm_started(self, x_n: np.ndarray, predicted: np.ndarray) -> np.ndarray:
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
        pot = self.potential
        if not self.warm_start or x_n.size == 0:
            return x_n
        y_n = pot.to_unknowns(x_n)
        p = pot.to_unknowns(predicted - x_n)
        if pot.fixed_dofs is not None:
            p[pot.fixed_dofs] = 0.0
        if not np.any(p):
            return x_n
        pot.solution_changed(y_n)
        in_contact = self.barrier is not None and self.barrier.pairs.n_pairs > 0
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

    def _solve(self, x_n: np.ndarray) -> tuple[NewtonResult, int, bool]:
        """Minimise; with friction, the outer lagged-friction loop of Algorithm 1.

        The loop ends when a minimisation under freshly lagged friction data needs no Newton
        step (its first increment is already below the tolerance), or at the cap, which is
        reported (``friction_converged = False``), not silent.
        """
        y = self.potential.to_unknowns(x_n)
        if self.friction is None:
            result = minimize(
                self.potential, y, options=self.newton, linear_solver=self.linear_solver
            )
            return result, 0, True
        cap = self.model.contact.friction_iterations
        total_it = 0
        for j in range(cap):
            self.friction.lag(self.potential.to_positions(y))
            if j > 0 and self._increment_below_tol(y, result):
                result.nit = total_it
                return result, j + 1, True
            result = minimize(
                self.potential, y, options=self.newton, linear_solver=self.linear_solver
            )
            total_it += result.nit
            if not result.success:
                return result, j + 1, False
            if j > 0 and result.nit == 0:
                result.nit = total_it
                return result, j + 1, True
            y = result.x
        result.nit = total_it
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

    def _begin_potential(self, ctx: StepContext, frames: NodeFrames | None) -> None:
        """Start the step's potential with the integrator's weights (eq. 22)."""
        integ = self.integrator
        self.potential.begin_step(
            ctx, integ.weight(self.dt), frames, contact_weight=integ.contact_weight(self.dt)
        )

    def _memory_gradient(self, x: np.ndarray) -> np.ndarray:
        """The gradient ``(n_dof,)`` in N whose force is carried as a^n into the next step: all
        potentials, or all but the contact terms under ``implicit_contact``."""
        contact = False if self.integrator.implicit_contact else None
        return self.potential.potential_gradient(x, contact=contact)

    def begin_step(self, state: State) -> np.ndarray:
        """Set up the potential of the step starting at ``state`` (for inspection and tests).

        Returns the start positions of the unknowns x^n ``(n_dof,)``; ``self.context`` holds the
        step context.
        """
        ctx, _, x_n, _, _, frames = self._setup(state, state.t + self.dt)
        self._begin_potential(ctx, frames)
        self.context = ctx
        return x_n

    def initialize(self, state: State) -> State:
        """Set a^0 of FEM nodes consistently with the forces at t = 0 (Newmark needs it)."""
        out = state.copy()
        if not self.integrator.uses_acceleration or self.model.n_fem_nodes == 0:
            return out
        ctx, _, x_n, _, _, _ = self._setup(state, state.t)
        self._begin_potential(ctx, None)
        self.potential.solution_changed(x_n)
        accel = -self._memory_gradient(x_n) / ctx.dof_mass
        all_a = self.layout.expand(accel)
        out.fem_a = all_a[: self.model.n_fem_nodes]
        # MPM particles start with a = g (no elastic force in the rest state)
        if self.model.n_particles:
            out.mpm_a = np.broadcast_to(self.model.gravity, out.mpm_a.shape).copy()
        return out

    # ------------------------------------------------------------------ the step
    def step(self, state: State) -> tuple[State, StepReport]:
        """Advance ``state`` by ``dt``; raises ``StepError`` when Newton fails."""
        started = time.perf_counter()
        dt, integ = self.dt, self.integrator
        t_next = state.t + dt
        ctx, mpm, x_n, v_n, a_n, frames = self._setup(state, t_next)
        layout = ctx.layout
        self._begin_potential(ctx, frames)
        self._adapt_kappa(ctx, x_n)
        setup_time = time.perf_counter() - started
        if layout.n_dof == 0:  # every node scripted: nothing to solve
            result = NewtonResult(
                x=x_n,
                success=True,
                status=NewtonStatus.CONVERGED,
                message="no unknowns",
                step_inf_norm=0.0,
            )
            friction_its, friction_ok = 0, True
        else:
            # a^{n+1} ~ a^n in eq. 21: x^{n+1} ~ x_hat + 2 alpha beta dt^2 a^n (warm start)
            self._predicted = ctx.x_hat + integ.weight(dt) * a_n if self.warm_start else None
            result, friction_its, friction_ok = self._solve_scripted(ctx, state, mpm)
        report_args = dict(
            friction_iterations=friction_its,
            friction_converged=friction_ok,
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
        # a^{n+1} from the forces at x^{n+1} (Algorithm 2, line 14), then eq. 21 for v; with
        # implicit contact, a^{n+1} leaves the contact forces out and they act as an impulse.
        x_next = self.potential.to_positions(result.x)
        a_contact = None
        if layout.n_dof:
            self.potential.solution_changed(result.x)
            a_next = -self._memory_gradient(x_next) / ctx.dof_mass
            if integ.implicit_contact and self.barrier is not None:
                a_contact = -self.potential.potential_gradient(x_next, contact=True) / ctx.dof_mass
        else:
            a_next = np.zeros(0)
        boundary_forces = None
        if frames is not None:
            # along slip normals the node moves with the boundary: its velocity, no acceleration
            normal_dofs = frames.normal_dofs()
            local = frames.to_local(a_next)
            local[normal_dofs] = 0.0
            a_next = frames.to_global(local)
            boundary_forces = self._boundary_forces(result, frames, mpm, layout)
        v_next = integ.velocity(v_n, a_n, a_next, dt)
        if a_contact is not None:
            v_next = integ.contact_velocity(v_next, a_contact, dt)
        if frames is not None:
            local = frames.to_local(v_next)
            local[normal_dofs] = frames.to_local((self.x_start - x_n) / dt)[normal_dofs]
            v_next = frames.to_global(local)

        g2p_start = time.perf_counter()
        new = self._advance(state, ctx, mpm, x_next, v_next, a_next, t_next)
        timings = dict(result.timings)
        timings["setup"] = setup_time
        timings["g2p"] = time.perf_counter() - g2p_start
        checked = time.perf_counter()  # independent of the barrier: bfemp.contact.intersection
        crossing = None if self.barrier is None else step_intersection(self.model, state, new)
        if crossing is not None:
            report_args.update(success=False, status=crossing.status, message=crossing.message)
            raise StepError(StepReport(**report_args, timings=timings))
        timings["intersection"] = time.perf_counter() - checked
        timings["step"] = time.perf_counter() - started
        if self.barrier is not None and self.barrier.pairs is not None:
            min_d = self.barrier.min_distance()
            report_args["min_distance"] = min_d if np.isfinite(min_d) else float("nan")
            report_args["contact_pairs"] = self.barrier.pairs.n_pairs
            if self.adaptive is not None:
                self.adaptive.after_step(min_d, self.model.contact.dhat)
        if boundary_forces is not None:
            report_args["boundary_forces"] = boundary_forces
        report = StepReport(**report_args, timings=timings)
        log.debug("step %d: %d Newton iterations", report.step, report.newton_iterations)
        return new, report

    def _advance(
        self,
        state: State,
        ctx: StepContext,
        mpm: MpmStep | None,
        x_next: np.ndarray,
        v_next: np.ndarray,
        a_next: np.ndarray,
        t_next: float,
    ) -> State:
        """The new state: FEM nodes from the solve, particles by G2P."""
        model, layout, n_fem = self.model, ctx.layout, self.model.n_fem_nodes
        x_all = layout.positions(x_next, ctx.fixed_positions)
        v_all = layout.expand(v_next)
        a_all = layout.expand(a_next)
        if mpm is not None and mpm.constraints.sticky.any():  # sticky nodes ride the boundary
            sticky = np.flatnonzero(mpm.constraints.sticky)
            v_all[n_fem + sticky] = mpm.constraints.shift[sticky] / self.dt
        new = state.copy()
        new.t = t_next
        new.step = state.step + 1
        prescribed = model.fem_prescribed
        v_scripted = model.prescribed_velocities(t_next)
        new.fem_x = x_all[:n_fem].copy()
        new.fem_v = np.where(prescribed[:, None], v_scripted, v_all[:n_fem])
        new.fem_a = a_all[:n_fem].copy()
        new.fem_a[prescribed] = (v_scripted[prescribed] - state.fem_v[prescribed]) / self.dt
        if mpm is not None:
            st = mpm.stencils
            grid_x_new = x_all[n_fem:]
            args = (self.transfer, st.nodes, st.weights, st.grads, st.active_x, grid_x_new)
            update = grid_to_particles(
                *args,
                mpm.fields.velocity,
                v_all[n_fem:],
                None,
                state.mpm_x,
                state.mpm_v,
                state.mpm_F,
            )
            new.mpm_x, new.mpm_v, new.mpm_F = update.mpm_x, update.mpm_v, update.mpm_F
            new.mpm_C = update.mpm_C
            if mpm.acceleration is not None:  # a^{n+1} crosses back like the velocity
                accel = grid_to_particles(
                    *args,
                    mpm.acceleration,
                    a_all[n_fem:],
                    None,
                    state.mpm_x,
                    state.mpm_a,
                    state.mpm_F,
                )
                new.mpm_a, new.mpm_Ca = accel.mpm_v, accel.mpm_C
        return new
