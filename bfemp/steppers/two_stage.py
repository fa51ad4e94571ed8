"""``"two_stage"``: explicit free motion, then frictional contact as a minimisation (TS notes).

One step (h = dt):

1. **Stage 1, free motion** (the explicit engine, ``ExplicitStepper``): P2G at x_p^n, grid
   v*_i = v_i^n + h (f_i^int(F^n) + m_i g) / m_i, FEM v*_n = v_n^n + h (f_ext - f_int(x^n))_n /
   m_n; scripted FEM nodes take their scripted velocity. No contact.
2. **Stage 2, contact** (``resolve``, before G2P): over the free FEM nodes and the active grid
   nodes that are not sticky, x = x^n + h v, minimise

       E(x) = 1/2 ||x - x*||_M^2 + h^2 (B(x) + D(x)),     x* = x^n + h v*,

   that is TS's 1/2 ||v - v*||_M^2 + l_c(J v) times h^2: BFEMP's incremental potential
   (``IncrementalPotential(InertiaTerm(), [BarrierTerm, FrictionTerm])``) with the inertial
   prediction replaced by the free motion and without elasticity or gravity (they are in x*).
   Its stationarity M (v - v*) = h J^T gamma (gamma = -grad(B + D), the barrier and lagged
   friction forces at the particles; J the B-spline G2P weights) is TS's linearised momentum
   balance. Collision points and pairs are the barrier's (``bfemp.contact.collision``: particles
   against FEM boundary facets, FEM-FEM boundary pairs), and the solve is the barrier's
   (``bfemp.steppers._barrier_solve.ScriptedSolve``: projected Newton of ``solvers.minimize``,
   CCD-filtered line search, scripted nodes brought to their targets without crossing).
   Level-set constraints are those the engine applies next (decided on v*): sticky nodes are not
   unknowns, slip nodes keep their normal coordinate (rotated frames), as in ``barrier``.
3. v = (x - x^n) / h on every node; G2P (the engine's) from the solved grid velocities, so
   x_p^{n+1} = sum_i w_ip x_i is exactly the barrier's collision point: no particle crosses a
   FEM boundary, whatever the velocity. The time step is bounded by the explicit elasticity
   only (``stable_dt``, the engine's).

Choices (not in the notes):

- Friction is semi-implicit by default (``friction="once"``): lagged once per step at x^n
  (normal forces and tangent bases of the contacts active at x^n), one minimisation; ``"loop"``
  runs the BFEMP friction loop (re-lag at the solution until a minimisation needs no Newton
  step, capped by ``scene.set_contact(friction_iterations=...)``). ``"once"`` is the default:
  fewer Newton iterations on issue 40's drop (design note ``measurements``, two_stage).
- Newton starts at x* when the straight move x^n -> x* passes CCD and no scripted node moves
  in the step, else at x^n; by default (``start="auto"``) also at x^n when friction has a
  contact within d-hat at x^n. From x* the inertia gradient sums to zero and every barrier
  and friction block has translations in its kernel (also after PSD projection), so each
  Newton iterate keeps sum M (x - x*) = 0: linear momentum of free bodies is exact
  (TS). From x^n it is so only to the Newton tolerance. x^n under friction (issue 40): from x*
  every contact starts sliding a full step v* dt, far beyond the mollifier's stick width
  eps_v dt, and Newton crossed back into sticking in backtracking steps; from x^n every lagged
  contact starts in the stick regime, where its quadratic model is exact (measured: design note
  ``measurements``, two_stage).
- ``StepReport.residual`` is the relative stationarity residual
  ||M (v - v*) - h J^T gamma||_inf / max(||M v*||_inf, ||h J^T gamma||_inf) at the returned
  step (dimensionless here; over the unknowns, slip-normal coordinates excluded).
- ``kappa = "auto"`` is refused (its gradient balance needs the elastic gradient the stage-2
  potential does not hold).
- Under friction the sliding of a node over the step is x - x^n (backward Euler on contact).
- Level-set reactions (``StepReport.boundary_forces``) are those of the engine's pass after the
  contact solve, which finds the constraints already met: they are zero (not reported).
- Newton runs without ``NewtonOptions``' near-solution acceptance (``near_solution_factor =
  0``): at static friction it took steps on a falling gradient norm that raised the energy, and
  Armijo stepped back, a 2-cycle until MAX_ITERATIONS.
- An independent check after the step (``bfemp.contact.intersection``) fails the step as
  ``INVERTED`` if a FEM cell or particle ended with det F <= 0 (checked first), else as
  ``INTERSECTION`` or ``TUNNELED`` if anything ended inside or went through a FEM body along
  the step's straight-line motion, as in ``barrier``. Nothing else keeps J > 0: the CFL bound
  of stage 1 is one of linear stability, and the explicit free motion x* of a soft cell crushed
  in an impact can be inverted; stage 2 holds no elasticity term, so neither its energy (+inf at
  J <= 0) nor its det F line-search filter (section 5) stops Newton following E toward x*
  (issue 44).

Measured results (Newton iterations, momentum drift, residuals, creep at static friction):
design note ``measurements``, two_stage.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from bfemp.contact.friction import FrictionTerm
from bfemp.contact.intersection import step_intersection, step_inversion
from bfemp.contact.pairs import find_pairs
from bfemp.contact.parameters import warn_mpm_pairs
from bfemp.contact.term import BarrierTerm
from bfemp.mpm.step import constrained_mpm_step
from bfemp.mpm.transfer import GridFields
from bfemp.potential import IncrementalPotential
from bfemp.state import State
from bfemp.steppers._barrier_potential import contact_view, has_contact
from bfemp.steppers._barrier_solve import ScriptedSolve
from bfemp.steppers._scaffold import StepNodes, nodes_of_step
from bfemp.steppers.base import ContactView, StepError, finite_or_nan
from bfemp.steppers.capabilities import BARRIER_PAIRS, Capabilities
from bfemp.steppers.explicit import ExplicitOptions, ExplicitStepper, GridStep, Motion
from bfemp.terms import InertiaTerm
from solvers.choice import LINEAR_SOLVER_NAMES, make_linear_solver
from solvers.options import NewtonOptions

__all__ = ["FRICTION_LAGGING", "STARTS", "TwoStageOptions", "TwoStageStepper"]


#: the names ``TwoStageOptions.friction`` accepts
FRICTION_LAGGING = ("once", "loop")
#: the names ``TwoStageOptions.start`` accepts
STARTS = ("auto", "free", "start")


@dataclass(frozen=True, kw_only=True)
class TwoStageOptions(ExplicitOptions):
    """Options of ``"two_stage"``.

    Attributes:
        friction: friction lagging, ``"once"`` (lagged at x^n, one minimisation per step: TS's
            semi-implicit friction) or ``"loop"`` (BFEMP's friction loop, capped by the
            scene's ``friction_iterations``).
        tol: Newton tolerance in m/s: the contact solve has converged when its increment moves
            no FEM node, particle position or (times dx) particle deformation gradient by more
            than ``tol * dt`` (as ``BarrierOptions.tol``).
        max_newton_iterations: Newton iteration cap per minimisation (200, as ``barrier``'s: the
            conformance catalogue's frictional ``stack`` took 133 in its hardest step).
        start: Newton's start, ``"auto"`` (as ``"free"``, but x^n when friction has a contact
            within d-hat at x^n: module docstring, issue 40), ``"free"`` (the free motion x*,
            when the move there passes CCD and no scripted node moves; else x^n) or
            ``"start"`` (always x^n).
        linear_solver: the linear solver of the contact solve (names of
            ``BarrierOptions.linear_solver``).
        cfl_safety_fem, cfl_safety_mpm: as in ``ExplicitOptions``.
    """

    strategy: ClassVar[str] = "two_stage"

    friction: str = "once"
    tol: float = field(
        default=1e-6, metadata={"unit": "velocity", "sweep": {"finer": -1, "factor": 10.0}}
    )
    max_newton_iterations: int = 200
    start: str = "auto"
    linear_solver: str = "default"

    def __post_init__(self) -> None:
        super().__post_init__()
        self.check_numbers("tol", what="a Newton tolerance in m/s")
        self.check_integers("max_newton_iterations", low=1)
        self.check_choices(
            friction=FRICTION_LAGGING, start=STARTS, linear_solver=LINEAR_SOLVER_NAMES
        )


@dataclass
class _Solved:
    """What the contact solve of the last step left (for the residual check, ``stationarity``)."""

    friction_ok: bool
    y: np.ndarray  # the solver's unknowns at the solution
    v_star: np.ndarray  # (n_dof,) free-motion velocities of the unknowns, m/s
    mass: np.ndarray  # (n_dof,) lumped masses of the unknowns, kg (kg/m in 2D)


class TwoStageStepper(ExplicitStepper):
    """The ``"two_stage"`` strategy (module docstring)."""

    name: ClassVar[str] = "two_stage"
    Options: ClassVar[type[TwoStageOptions]] = TwoStageOptions
    #: stage 2 is the barrier's contact solve at the particles (TS notes): the barrier's pairs,
    #: particles and FEM nodes against FEM boundaries; MPM bodies share the engine's grid
    capabilities: ClassVar[Capabilities] = Capabilities(
        pairs=BARRIER_PAIRS,
        needs_contact_settings=True,
        penetration_bound_cells=0.0,
        penetration_note="none: the contact stage is the barrier's CCD-filtered solve; a step "
        "that would cross is a named failure (TUNNELED, INTERSECTION)",
    )

    def _setup(self) -> None:
        """The strategy's own construction, after the engine's (module docstring)."""
        model = self.model
        opts = self.options
        self.barrier: BarrierTerm | None = None
        self.friction: FrictionTerm | None = None
        self.potential: IncrementalPotential | None = None
        #: the last step's contact solve (``stationarity``)
        self._last_solve: _Solved | None = None
        self._contact: ContactView | None = None
        if not has_contact(model):
            return
        c = model.contact
        if c.adaptive_kappa:
            raise ValueError(
                "two_stage: contact kappa = 'auto' is not supported (its gradient balance needs "
                "the elastic forces, which stage 2 does not hold); give "
                "scene.set_contact(kappa=...)"
            )
        self.barrier = BarrierTerm(c.dhat, c.kappa)
        terms: list = [self.barrier]
        if c.has_friction:
            warn_mpm_pairs(c, "two_stage", [b.name for b in model.mpm_bodies])
            self.friction = FrictionTerm(c.friction, c.eps_v, self.barrier)
            terms.append(self.friction)
        self.potential = IncrementalPotential(InertiaTerm(), terms)
        self.newton = NewtonOptions(
            tol=opts.tol,
            max_iter=opts.max_newton_iterations,
            step_scale=self.dt,
            # no step taken on a falling gradient norm alone (NewtonOptions.near_solution_factor:
            # at static friction it cycled); the stage-2 energy has no stiff elastic term whose
            # round-off would need it
            near_solution_factor=0.0,
        )
        self._solver = ScriptedSolve(
            self,
            make_linear_solver(opts.linear_solver, block_size=model.dim),
            take_last_increment=True,
            friction_loop=opts.friction == "loop",
        )

    @property
    def terms(self) -> list[str]:
        """Stage 1's force terms, then stage 2's (inertia about x*, barrier, friction)."""
        stage2 = [] if self.potential is None else [t.name for t in self.potential.terms]
        return [*super().terms, *stage2]

    # ------------------------------------------------------------------ the step
    def after_g2p(self, step: GridStep, motion: Motion) -> None:
        """The independent crossing check of the end positions (``StepError`` on an inverted
        cell or particle or a crossing: stage 2 has no elasticity, nor its det F filter, so
        nothing in the solve keeps J > 0), then the contact solve's report."""
        if self.potential is None:
            return
        t0 = time.perf_counter()
        # the checks read the end positions and F, which ``motion`` carries under State's names
        model, state = self.model, step.state
        crossing = step_inversion(model, motion) or step_intersection(model, state, motion)
        step.timings["intersection"] = time.perf_counter() - t0
        if crossing is not None:
            raise StepError(
                step.report(success=False, status=crossing.status, message=crossing.message)
            )
        abs_r, scale = self.stationarity()
        step.notes.extend(self._solver.rounding_notes())
        if not self._last_solve.friction_ok:
            step.notes.append("FRICTION_LOOP: the friction loop did not converge within its cap")
        step.outcome.update(
            residual=abs_r / scale if scale > 0.0 else 0.0,
            min_distance=finite_or_nan(self.barrier.min_distance()),
            contact_pairs=int(self.barrier.pairs.n_pairs),
            friction_converged=self._last_solve.friction_ok,
        )

    def resolve(
        self, step: GridStep, grid_v: np.ndarray, fem_v: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Stage 2: the contact minimisation about the free motion v* (module docstring).

        Args:
            step: the engine's step (P2G fields at x^n).
            grid_v: free-motion grid velocities v* ``(1, G, d)`` in m/s (the one field).
            fem_v: free-motion FEM node velocities v* ``(N, d)`` in m/s (scripted: scripted).

        Returns:
            The end-of-step velocities ``(1, G, d)`` and ``(N, d)`` in m/s.
        """
        self._last_solve, self._contact = None, None
        if self.potential is None:
            step.iterations.update(newton=0, friction=0)
            return grid_v, fem_v
        self._solver.shifted_solves, self._solver.max_shift = 0, 0.0  # this step's note only
        started = time.perf_counter()
        model, h, state = self.model, self.dt, step.state
        n_fem = model.n_fem_nodes
        grid_v = grid_v[0]
        nodes = self._nodes(step, state, grid_v)
        layout, pot = nodes.layout, self.potential
        v_star_all = np.concatenate([fem_v, grid_v]) if nodes.mpm is not None else fem_v
        x_hat_all = nodes.x + h * v_star_all
        ctx = nodes.context(model, state, x_hat_all)
        if self.friction is not None:  # sliding over the step: x - x^n on every node
            ctx.sliding = (1.0, -nodes.x)
        pot.begin_step(ctx, h * h, nodes.frames)
        x_start = nodes.start()
        setup = time.perf_counter() - started
        if layout.n_dof == 0:
            y, nit, f_its, f_ok, status = pot.to_unknowns(x_start), 0, 0, True, "EXPLICIT"
            free = False
            pot.solution_changed(y)
            timings: dict[str, float] = {}
        else:
            x0, free = self._newton_start(nodes, x_start, ctx.x_hat, state)
            result, f_its, f_ok = self._solver.solve(state, nodes, x0, ctx.x_hat, None, x_start)
            if not result.success:
                raise StepError.failed(
                    state.step + 1,
                    step.t_next,
                    result.status.name,
                    f"two_stage contact solve: {result.message}",
                    iterations={"newton": int(result.nit), "friction": f_its},
                    timings=dict(result.timings),
                )
            y, nit, status = result.x, int(result.nit), result.status.name
            pot.solution_changed(y)  # the barrier at the solution (distances, contact())
            timings = dict(result.timings)
        x_all = layout.positions(pot.to_positions(y), nodes.fixed)
        v_all = (x_all - nodes.x) / h
        self._last_solve = _Solved(f_ok, y, layout.restrict(v_star_all), ctx.dof_mass)
        timings["contact_setup"] = setup
        timings["contact"] = time.perf_counter() - started
        step.timings.update(timings)
        step.iterations.update(newton=nit, friction=f_its)
        step.status = status
        step.message = "explicit free motion, implicit contact solve" + (
            " (Newton from x*)" if free else " (Newton from x^n)"
        )
        fem_out = v_all[:n_fem].copy()
        grid_out = v_all[n_fem:].copy() if nodes.mpm is not None else grid_v
        return grid_out[None], fem_out

    def _nodes(self, step: GridStep, state: State, grid_v: np.ndarray) -> StepNodes:
        """All-node fields of the step from the engine's P2G (``nodes_of_step``); level-set
        constraints decided on v* as the engine does next (``constrained_mpm_step``)."""
        model = self.model
        if model.n_particles == 0:
            return nodes_of_step(model, state, None, dt=self.dt, t_next=step.t_next)
        stencils = step.stencils()
        if stencils.n_nodes != step.grid_x.shape[0] or not np.array_equal(
            stencils.active_x, step.grid_x
        ):
            raise RuntimeError("two_stage: the engine's grid nodes differ from the stencils'")
        fields = GridFields(mass=step.mass[0], velocity=step.velocity[0])
        mpm = constrained_mpm_step(model, stencils, fields, grid_v, step.t_next, self.dt)
        return nodes_of_step(model, state, mpm, dt=self.dt, t_next=step.t_next)

    def _newton_start(
        self, nodes: StepNodes, x_start: np.ndarray, x_hat: np.ndarray, state: State
    ) -> tuple[np.ndarray, bool]:
        """x* (slip-normal coordinates kept) when ``start="free"`` (or ``"auto"`` with no
        friction contact within d-hat at x^n), no scripted node moves and the straight move
        x^n -> x* passes CCD with a finite energy; else x^n."""
        pot = self.potential
        if self.options.start == "start":
            return x_start, False
        if self.options.start == "auto" and self.friction is not None:
            bar = self.barrier
            near = find_pairs(
                bar.collisions, bar.collision_positions(pot.to_unknowns(x_start)), bar.dhat
            )
            if near.n_pairs:  # friction lagged at x^n: start where its sliding is zero
                return x_start, False
        model = self.model
        moving = not np.array_equal(
            nodes.fixed[: model.n_fem_nodes][model.fem_prescribed],
            state.fem_x[model.fem_prescribed],
        )
        if moving or (nodes.mpm is not None and nodes.mpm.constraints.shift.any()):
            return x_start, False
        y0 = pot.to_unknowns(x_start)
        p = pot.to_unknowns(x_hat - x_start)
        if pot.fixed_dofs is not None:
            p[pot.fixed_dofs] = 0.0
        pot.solution_changed(y0)
        if pot.max_step_size(y0, p) < 1.0:
            return x_start, False
        pot.solution_changed(y0 + p)
        if not np.isfinite(pot.value(y0 + p)):
            return x_start, False
        return pot.to_positions(y0 + p), True

    # ------------------------------------------------------------------ checks and reporting
    def stationarity(self, contact: bool = True) -> tuple[float, float]:
        """Stationarity residual of the last step's contact solve.

        r = M (v - v*) - h J^T gamma over the unknowns (slip-normal coordinates excluded), with
        gamma the barrier and lagged friction forces at the solution; ``contact=False`` drops
        the gamma term (the negative control: r = M (v - v*)).

        Returns:
            ``(||r||_inf, scale)`` in N s (N s/m in 2D), scale = max(||M v*||_inf,
            ||h J^T gamma||_inf); ``(0, 0)`` before a contact solve.
        """
        solved, pot = self._last_solve, self.potential
        if solved is None or pot is None or solved.y.size == 0:
            return 0.0, 0.0
        h = self.dt
        pot.solution_changed(solved.y)
        x = pot.to_positions(solved.y)
        inertia = pot.inertia.gradient(x) / h  # M (v - v*)
        contact_force = -h * pot.potential_gradient(x)  # h J^T gamma
        r = inertia - contact_force if contact else inertia
        mass = solved.mass
        free = None if pot.fixed_dofs is None else ~pot.fixed_dofs
        r_local = pot.to_unknowns(r)
        if free is not None:
            r_local = r_local[free]
        scale = max(
            float(np.abs(mass * solved.v_star).max(initial=0.0)),
            float(np.abs(contact_force).max(initial=0.0)),
        )
        return float(np.abs(r_local).max(initial=0.0)), scale

    def contact(self) -> ContactView:
        """Barrier forces, closest distance, active pairs and energy at the end of the last step
        (``barrier``'s ``contact_view``); the engine's empty view without a contact term."""
        if self.barrier is None:
            return super().contact()
        if self._contact is None:
            self._contact = contact_view(self.model, self.barrier)
        return self._contact
