"""The ``"barrier"`` strategy: BFEMP's implicit step (Algorithm 1; contact in the same potential).

One step:
1. MPM: quadratic B-spline stencils at x_p^n and P2G of mass, velocity (and acceleration for
   Newmark) per Tables 1-3 (line 2); level-set constraints of the active grid nodes
   (``bfemp.mpm.step.prepare_mpm_step``).
2. Unknowns: free FEM nodes and unconstrained grid nodes, prescribed FEM nodes follow their motion,
   sticky grid nodes stay, slip grid nodes move tangentially only (rotated frames).
3. Predict x_hat (BFEMP eqs. 21-22), minimise the incremental potential with projected Newton from
   x^n (Algorithm 2; scripted nodes brought to their targets without crossing, the outer friction
   loop of Algorithm 1: ``bfemp.steppers._barrier_solve``), then a^{n+1} from BFEMP eq. 21 and the
   solved x^{n+1} (equal to Algorithm 2 line 14's -M^-1 dPsi/dx at the exact minimiser;
   ``Integrator.acceleration`` says why) and the velocity update of BFEMP eq. 21; constrained
   components get zero velocity and acceleration. Under an integrator with ``implicit_contact``
   the contact forces are kept out of a^{n+1} and added to the velocity as an impulse
   (``bfemp.integrators``).
4. MPM: one G2P of positions, velocities, F (and APIC C, Newmark a) per Tables 1-3 (line 12)
   (``bfemp.steppers._scaffold.write_state``).
5. An independent check (``bfemp.contact.intersection``): no FEM cell or particle inverted
   (else ``INVERTED``, checked first), no node or particle ends inside another FEM body, or
   went through one along the step's straight-line motion (an exact CCD of x^n -> x^{n+1});
   otherwise the step fails as ``INTERSECTION`` or ``TUNNELED`` (the barrier keeps every
   Newton iterate clear, but with |v| dt far above the bodies' size frictionless iterates can
   take them around each other in configuration space).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import time
from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from bfemp.contact.adaptive import AdaptiveKappa
from bfemp.contact.friction import FrictionTerm
from bfemp.contact.intersection import step_intersection, step_inversion
from bfemp.contact.term import BarrierTerm
from bfemp.integrators import Integrator
from bfemp.model import Model
from bfemp.mpm.step import prepare_mpm_step
from bfemp.state import State
from bfemp.steppers._barrier_options import LINEAR_SOLVERS, BarrierOptions
from bfemp.steppers._barrier_potential import build_potential, contact_view, has_contact
from bfemp.steppers._barrier_solve import ScriptedSolve
from bfemp.steppers._scaffold import StepNodes, StepPhases, nodes_of_step, write_state
from bfemp.steppers.base import ContactView, StepError, StepReport, finite_or_nan
from bfemp.steppers.capabilities import BARRIER_PAIRS, Capabilities
from bfemp.terms import StepContext
from solvers.linear import LinearSolver
from solvers.options import NewtonOptions
from solvers.result import NewtonResult, NewtonStatus

__all__ = ["LINEAR_SOLVERS", "BarrierOptions", "BarrierStepper", "build_potential", "has_contact"]

log = logging.getLogger(__name__)

#: the note of a step whose friction loop stopped unconverged (at its cap, or stalled)
FRICTION_LOOP_NOTE = "FRICTION_LOOP: the friction loop did not converge within its cap"


class BarrierStepper:
    """The ``"barrier"`` strategy: one incremental-potential minimisation per step.

    Args:
        model: the static model.
        integrator: Newmark-family parameters (implicit; ``bfemp.integrators``).
        transfer: MPM particle-grid transfer, ``"apic"``, ``"pic"`` or ``"flip"``.
        dt: time step in s.
        options: ``BarrierOptions`` (defaults when None).
    """

    name: ClassVar[str] = "barrier"
    Options: ClassVar[type] = BarrierOptions
    explicit: ClassVar[bool] = False
    #: BFEMP couples particles and FEM nodes with FEM boundaries through the barrier
    #: (BFEMP eq. 27) and MPM bodies through their shared grid (never particle-particle,
    #: BFEMP section 4)
    capabilities: ClassVar[Capabilities] = Capabilities(
        pairs=BARRIER_PAIRS,
        needs_contact_settings=True,
        penetration_bound_cells=0.0,
        penetration_note="none: the CCD- and det F-filtered line search keeps every particle "
        "and node outside FEM bodies; a step that would cross is a named failure (TUNNELED, "
        "INTERSECTION)",
        inversion_free=True,
    )

    def __init__(
        self,
        model: Model,
        *,
        integrator: Integrator,
        transfer: str = "apic",
        dt: float,
        options: BarrierOptions | None = None,
    ) -> None:
        options = BarrierOptions() if options is None else options
        if not isinstance(options, BarrierOptions):
            raise ValueError(
                f"strategy 'barrier' takes BarrierOptions, got {type(options).__name__}"
            )
        if getattr(integrator, "explicit", False):
            raise ValueError(
                f"strategy 'barrier' is implicit: integrator {integrator.name!r} is explicit "
                "(use backward_euler, newmark, newmark_damped or newmark_implicit_contact)"
            )
        self.model = model
        self.options = options
        self.integrator = integrator
        self.dt = float(dt)
        self.newton = NewtonOptions(
            tol=options.tol, max_iter=options.max_newton_iterations, step_scale=self.dt
        )
        self.transfer = transfer
        self.potential = build_potential(model)
        self.barrier = next(
            (t for t in self.potential.potentials if isinstance(t, BarrierTerm)), None
        )
        self.friction = next(
            (t for t in self.potential.potentials if isinstance(t, FrictionTerm)), None
        )
        self.adaptive: AdaptiveKappa | None = None
        self._contact: ContactView | None = None  # contact() of the last step, once asked
        self._setup_parts: dict[str, float] = {}  # seconds of the last _begin, by part
        self._solver = ScriptedSolve(
            self,
            options.make_linear_solver(model.dim),
            take_last_increment=options.velocity_update == "positions",
            back_solve_stop=options.friction_back_solve,
        )

    @property
    def linear_solver(self) -> LinearSolver:
        """The linear solver of the Newton loop; assigning one makes the next steps factorise
        (and analyse) with it."""
        return self._solver.linear_solver

    @linear_solver.setter
    def linear_solver(self, solver: LinearSolver) -> None:
        self._solver.linear_solver = solver

    @property
    def warm_start(self) -> bool:
        """Whether Newton starts from the predicted x^{n+1} (``BarrierOptions.warm_start``)."""
        return self.options.warm_start

    @property
    def terms(self) -> list[str]:
        """Names of the active energy terms."""
        return [term.name for term in self.potential.terms]

    def stable_dt(self, state: State) -> float:
        """Implicit: no stable-step bound (inf)."""
        return float("inf")

    # ------------------------------------------------------------------ step set-up
    def _begin(
        self, state: State, t_next: float, frames: bool = True
    ) -> tuple[StepNodes, StepContext]:
        """Gather the step's nodes (P2G at x^n), predict x_hat and begin the potential with the
        integrator's weights (BFEMP eq. 22); ``frames=False``: without slip frames."""
        integ, dt = self.integrator, self.dt
        started = time.perf_counter()
        model, mpm = self.model, None
        if model.n_particles:
            with_a = integ.uses_acceleration
            mpm = prepare_mpm_step(model, state, self.transfer, with_a, dt=t_next - state.t)
        nodes = nodes_of_step(model, state, mpm, dt=dt, t_next=t_next)
        gathered = time.perf_counter()
        x_hat_all = integ.predict(nodes.x, nodes.v, nodes.a, dt)
        ctx = nodes.context(model, state, x_hat_all)
        if self.friction is not None:  # the sliding map of BFEMP eq. 37
            ctx.sliding = self._sliding_map(nodes, x_hat_all)
        weights = integ.weight(dt), nodes.frames if frames else None
        self.potential.begin_step(ctx, *weights, contact_weight=integ.contact_weight(dt))
        # the parts of the step's "setup" phase: P2G and stencils, then the terms' begin_step
        self._setup_parts = {
            "setup_p2g": gathered - started,
            "setup_terms": time.perf_counter() - gathered,
        }
        return nodes, ctx

    def _sliding_map(self, nodes: StepNodes, x_hat_all: np.ndarray) -> tuple[float, np.ndarray]:
        """U = s y + c: each node's sliding dt v^{n+1} over the step, affine in its position y.

        Free nodes: dt v^n + dt^2 ((1 - gamma) a^n + gamma a^{n+1}) with a^{n+1} = (y - x_hat) /
        (2 alpha beta dt^2) (BFEMP eq. 21), so s = gamma / (2 alpha beta); scripted nodes: dt times
        their scripted velocity (sticky grid nodes: 0).
        """
        integ, dt = self.integrator, self.dt
        s = integ.gamma / (2.0 * integ.alpha * integ.beta)
        c = dt * nodes.v + dt * dt * (1.0 - integ.gamma) * nodes.a - s * x_hat_all
        v_end = np.zeros_like(nodes.x)
        n_fem = self.model.n_fem_nodes
        v_end[:n_fem] = self.model.prescribed_velocities(nodes.t_next)
        scripted = nodes.layout.dof_node < 0
        c[scripted] = dt * v_end[scripted] - s * nodes.fixed[scripted]
        return s, c

    def _adapt_kappa(self, x_n: np.ndarray) -> None:
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

    def _memory_gradient(self, x: np.ndarray) -> np.ndarray:
        """The gradient ``(n_dof,)`` in N whose force is carried as a^n into the next step: all
        potentials, or all but the contact terms under ``implicit_contact``."""
        contact = False if self.integrator.implicit_contact else None
        return self.potential.potential_gradient(x, contact=contact)

    def phases(self, state: State) -> StepPhases:
        """Begin the step from ``state`` without taking it: what its Newton solve starts from.

        The documented inspection hook (benchmarks, tests): the step is begun (``_begin``: P2G
        at x^n, x_hat of BFEMP eq. 22, the potential begun) exactly as ``step`` begins it,
        before the kappa update and the solve.
        Nothing is solved or written; ``step`` begins its own step again, so a ``step`` after
        ``phases`` gives the same state, bit for bit, as one without.
        """
        self._contact = None
        nodes, ctx = self._begin(state, state.t + self.dt)
        x0 = nodes.layout.restrict(nodes.x)
        return StepPhases(self.potential, ctx, x0, self.barrier, self.friction, self.linear_solver)

    def initialize(self, state: State) -> State:
        """Set a^0 of FEM nodes consistently with the forces at t = 0 (Newmark needs it)."""
        out = state.copy()
        if not self.integrator.uses_acceleration or self.model.n_fem_nodes == 0:
            return out
        nodes, ctx = self._begin(state, state.t, frames=False)
        x_n = nodes.layout.restrict(nodes.x)
        self.potential.solution_changed(x_n)
        accel = -self._memory_gradient(x_n) / ctx.dof_mass
        out.fem_a = nodes.layout.expand(accel)[: self.model.n_fem_nodes]
        # MPM particles start with a = g (no elastic force in the rest state)
        if self.model.n_particles:
            out.mpm_a = np.broadcast_to(self.model.gravity, out.mpm_a.shape).copy()
        return out

    # ------------------------------------------------------------------ the step
    def step(self, state: State) -> tuple[State, StepReport]:
        """Advance ``state`` by ``dt``; raises ``StepError`` when Newton fails."""
        started = time.perf_counter()
        hessian_before = self.potential.hessian_seconds()
        self._contact = None
        dt, integ = self.dt, self.integrator
        t_next = state.t + dt
        nodes, ctx = self._begin(state, t_next)
        layout = nodes.layout
        x_n, v_n, a_n = layout.restrict(nodes.x), layout.restrict(nodes.v), layout.restrict(nodes.a)
        self._adapt_kappa(x_n)
        setup_time = time.perf_counter() - started
        if layout.n_dof == 0:  # every node scripted: nothing to solve
            result = NewtonResult(
                x_n, True, NewtonStatus.CONVERGED, "no unknowns", step_inf_norm=0.0
            )
            friction_its, friction_ok = 0, True
        else:
            # a^{n+1} ~ a^n in BFEMP eq. 21: x^{n+1} ~ x_hat + 2 alpha beta dt^2 a^n (warm start)
            predicted = ctx.x_hat + integ.weight(dt) * a_n if self.warm_start else None
            result, friction_its, friction_ok = self._solver.solve(
                state, nodes, nodes.start(), ctx.x_hat, predicted
            )
        iterations = {"newton": int(result.nit)}  # and lagged-friction updates with friction
        if self.friction is not None:
            iterations["friction"] = friction_its
        report_args = dict(
            friction_converged=friction_ok,
            step=state.step + 1,
            t=t_next,
            success=bool(result.success),
            status=result.status.name,
            message=result.message,
            iterations=iterations,
            residual=float(result.step_inf_norm) / dt,
            notes=(
                *(self._solver.rounding_notes() if layout.n_dof else ()),
                *_zero_mass_notes(nodes),
                *(() if friction_ok else (FRICTION_LOOP_NOTE,)),
            ),
        )
        if not result.success:
            raise StepError(StepReport(**report_args, timings=dict(result.timings)))
        update_start = time.perf_counter()
        v_next, a_next, boundary_forces = self._end_velocities(result, nodes, x_n, v_n, a_n, ctx)
        g2p_start = time.perf_counter()
        x_all = layout.positions(self.potential.to_positions(result.x), nodes.fixed)
        ends = {"x_end": x_all, "v_end": layout.expand(v_next), "a_end": layout.expand(a_next)}
        new = write_state(self.model, state, nodes, transfer=self.transfer, **ends)
        timings = dict(result.timings)
        timings["setup"] = setup_time
        timings.update(self._setup_parts)
        timings["update"] = g2p_start - update_start
        timings["g2p"] = time.perf_counter() - g2p_start
        checked = time.perf_counter()  # independent of the barrier: bfemp.contact.intersection
        crossing = step_inversion(self.model, new)  # det F > 0 is kept by the line search
        if crossing is None and self.barrier is not None:
            crossing = step_intersection(self.model, state, new)
        if crossing is not None:
            report_args.update(success=False, status=crossing.status, message=crossing.message)
            raise StepError(StepReport(**report_args, timings=timings))
        timings["intersection"] = time.perf_counter() - checked
        timings["step"] = time.perf_counter() - started
        # the part of the Hessian phase spent projecting the elasticity terms' dP/dF to PSD (the
        # whole split by term: ``IncrementalPotential.hessian_seconds``)
        timings["hessian_projection"] = sum(
            seconds - hessian_before.get(part, 0.0)
            for part, seconds in self.potential.hessian_seconds().items()
            if part.endswith("/projection")
        )
        if self.barrier is not None and self.barrier.pairs is not None:
            min_d = self.barrier.min_distance()
            report_args["min_distance"] = finite_or_nan(min_d)
            report_args["contact_pairs"] = self.barrier.pairs.n_pairs
            if self.adaptive is not None:
                self.adaptive.after_step(min_d, self.model.contact.dhat)
        if boundary_forces is not None:
            report_args["boundary_forces"] = boundary_forces
        report = StepReport(**report_args, timings=timings)
        log.debug("step %d: %d Newton iterations", report.step, report.newton_iterations)
        return new, report

    def _end_velocities(
        self,
        result: NewtonResult,
        nodes: StepNodes,
        x_n: np.ndarray,
        v_n: np.ndarray,
        a_n: np.ndarray,
        ctx: StepContext,
    ) -> tuple[np.ndarray, np.ndarray, tuple | None]:
        """v^{n+1}, a^{n+1} ``(n_dof,)`` and the level-set reactions of a converged step.

        a^{n+1} from the solved positions (BFEMP eq. 21; Algorithm 2 line 14's -M^-1 dPsi/dx agrees
        at the exact minimiser, ``Integrator.acceleration`` says why the positions are taken;
        ``BarrierOptions.velocity_update = "forces"`` takes the forces, as the paper does),
        then BFEMP eq. 21 for v, so that v^{n+1} matches x^{n+1} - x^n; with implicit contact the
        elastic a^{n+1} comes from the forces and the contact part (the rest of the motion)
        acts as an impulse. Along slip normals the node moves with the boundary: its velocity,
        no acceleration.
        """
        integ, dt, frames = self.integrator, self.dt, nodes.frames
        x_next = self.potential.to_positions(result.x)
        a_contact = None
        if nodes.layout.n_dof:
            self.potential.solution_changed(result.x)
            from_forces = self.options.velocity_update == "forces"
            if integ.implicit_contact and self.barrier is not None:
                a_next = -self._memory_gradient(x_next) / ctx.dof_mass
                if from_forces:
                    contact = self.potential.potential_gradient(x_next, contact=True)
                    a_contact = -contact / ctx.dof_mass
                else:
                    a_contact = integ.contact_acceleration(x_next, ctx.x_hat, a_next, dt)
            elif from_forces:
                a_next = -self._memory_gradient(x_next) / ctx.dof_mass
            else:
                a_next = integ.acceleration(x_next, ctx.x_hat, dt)
        else:
            a_next = np.zeros(0)
        boundary_forces = None
        if frames is not None:
            normal_dofs = frames.normal_dofs()
            local = frames.to_local(a_next)
            local[normal_dofs] = 0.0
            a_next = frames.to_global(local)
            boundary_forces = self._boundary_forces(result, nodes)
        v_next = integ.velocity(v_n, a_n, a_next, dt)
        if a_contact is not None:
            v_next = integ.contact_velocity(v_next, a_contact, dt)
        if frames is not None:
            local = frames.to_local(v_next)
            local[normal_dofs] = frames.to_local((nodes.start() - x_n) / dt)[normal_dofs]
            v_next = frames.to_global(local)
        return v_next, a_next, boundary_forces

    def _boundary_forces(self, result: NewtonResult, nodes: StepNodes) -> tuple:
        """Reaction force (d,) in N of each level-set boundary on the body, from slip nodes.

        At the constrained optimum dE/dy_n = h^2 f_n for a fixed normal coordinate y_n: f_n is the
        force the boundary exerts along its normal (positive pushes the body away, negative pulls
        it: adhesion). Sticky nodes are not unknowns and are not included.
        """
        d, frames, mpm = self.model.dim, nodes.frames, nodes.mpm
        out = np.zeros((len(self.model.boundaries), d))
        if result.jac is None:
            return tuple(tuple(row) for row in out)
        f_n = np.asarray(result.jac)[frames.normal_dofs()] / self.integrator.weight(self.dt)
        normals = frames.frames[:, :, 0]
        grid_nodes = nodes.layout.free_nodes[frames.nodes] - mpm.node_offset
        owner = mpm.constraints.owner[grid_nodes]
        np.add.at(out, owner, f_n[:, None] * normals)
        return tuple(tuple(float(c) for c in row) for row in out)

    # ------------------------------------------------------------------ contact and checkpoints
    def contact(self) -> ContactView:
        """Barrier forces, closest distance, active pairs and energy at the end of the last step
        (``contact_view``; computed once per step)."""
        if self._contact is None:
            self._contact = contact_view(self.model, self.barrier)
        return self._contact

    def checkpoint_data(self) -> dict[str, np.ndarray]:
        """The adaptive-kappa state (``kappa = "auto"``), as a JSON string array."""
        if self.adaptive is None:
            return {}
        return {"adaptive": np.array(json.dumps(dataclasses.asdict(self.adaptive)))}

    def restore_checkpoint_data(self, data: Mapping[str, np.ndarray]) -> None:
        """Take back ``checkpoint_data``'s arrays."""
        unknown = sorted(set(data) - {"adaptive"})
        if unknown:
            raise ValueError(f"barrier stepper: unknown checkpoint data {unknown}")
        if "adaptive" in data:
            self.adaptive = AdaptiveKappa(**json.loads(str(data["adaptive"])))


def _zero_mass_notes(nodes: StepNodes) -> tuple[str, ...]:
    """The ``P2G_ZERO_MASS`` note when the step's P2G left grid nodes of (near) zero mass
    (``bfemp.mpm.transfer``; the lightest are pinned, ``bfemp.mpm.step``): a named note, so that
    a run warns once and counts the steps (it was a log warning in every step)."""
    light = 0 if nodes.mpm is None else int(nodes.mpm.fields.zero_mass_nodes)
    if not light:
        return ()
    return (
        f"P2G_ZERO_MASS: {light} grid nodes with (near) zero mass (only round-off B-spline "
        "weights reach them: particles a hair off a cell-centre line) start the step at zero "
        "velocity; the particles do not feel them",
    )
