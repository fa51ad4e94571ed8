"""The explicit engine shared by the explicit strategies (single_field, augury, lr, two_stage).

One step (symplectic Euler, ``bfemp.integrators.SYMPLECTIC_EULER``; USL for MPM):

1. MPM: quadratic B-spline weights at x_p^n; one fused parallel P2G of mass, momentum (APIC,
   PIC, FLIP) and internal force f_i = -sum_p V_p^0 P(F_p^n) (F_p^n)^T grad w_ip, which is
   ``-MpmElasticityTerm.gradient`` at the grid nodes' start positions (F_p(x^n) = F_p^n by
   linear completeness, BFEMP eq. 25). FEM: f_n = ``-ElasticityTerm.gradient`` of the cells at
   x^n over an all-free ``DofLayout`` (built once). Gravity m g and dead loads are added.
   (The phase ``particles_to_grid``; then phase ``after_p2g(step)``, default nothing.)
2. v* = v + dt M^-1 f on the grid nodes and the free FEM nodes (BFEMP eq. 21 with beta = 0; the
   stored velocity is the half-step one); scripted FEM nodes take their scripted velocity at
   t^{n+1}.
3. Phase ``resolve(step, grid_v, fem_v) -> (grid_v, fem_v)`` (default: unchanged): where a
   contact algorithm corrects v*.
4. Level-set boundaries on the grid nodes inside them (``bfemp.mpm.boundaries``, evaluated at
   x_i^n, the boundary where it is at t^{n+1}): sticky v = v_b; slip: the normal component of
   v - v_b removed; separate: as slip while (v* - v_b) . n < 0, free otherwise (decided on v*,
   the velocity the node would move with, unless a phase decided earlier: lr on v^n). The
   reaction m_i (v - v*) / dt of each boundary's nodes is reported in
   ``StepReport.boundary_forces`` (sticky nodes included).
5. FEM: x += dt v (scripted nodes: their scripted positions); MPM: phase ``g2p`` (default: the
   transfer of ``bfemp.mpm.transfer.grid_to_particles`` with x~_i = x_i + dt v_i, which gives
   x_p += dt v_p and F_p <- (I + dt grad v) F_p by linear completeness; allocation-free,
   ``bfemp.mpm.transfer.g2p_explicit``).
6. Phase ``after_g2p(step, motion)`` (default: nothing): a strategy corrects the end values
   (augury's contact correction); then ``Motion.commit`` writes the new state, the one place a
   step writes positions.

The phases exchange one value, ``GridStep`` (start state, grid fields with a field axis M,
constraints, and the report's iterations, notes, timings and extra), from which the engine
builds the ``StepReport``.

Two kernel paths, one result (tested to round-off): the 2D dense-box kernels
(``bfemp.mpm._dense2d_kernels``; ``GridStep.stencils()`` builds stencils for a strategy that
needs them) and, in 3D or for a sparse box, ``bfemp.mpm._explicit_kernels``.

Stable step: ``bfemp.steppers.stable_dt``. The constructor refuses a dt above the bound (with
the safety factors of the options) with a ``ValueError`` naming the bound, body and cell or
particle; ``dt="auto"`` takes it. Every step re-evaluates the bound (particle speeds and cell
shapes change): above the safety-scaled bound the report carries a ``CFL_ABOVE_SAFETY`` note;
above the unscaled bound (CFL number 1: a wave or particle crosses a whole cell or altitude in
one step) the step raises ``StepError`` with status ``CFL_VIOLATED`` and leaves the state alone.
The slack between the two lets ``dt="auto"`` run while bodies speed up.

MPM bodies all share one grid velocity field here (the P2G over all particles): bodies stick
tangentially where their stencils overlap (``single_field``). Strategies that keep fields apart
plug in phases (``lr`` keeps one field per body).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from bfemp.dofs import DofLayout
from bfemp.integrators import SYMPLECTIC_EULER, ExplicitIntegrator, integrator_from_name
from bfemp.model import Model
from bfemp.mpm.boundaries import material_constraints
from bfemp.mpm.transfer import (
    SCHEMES,
    dense_g2p,
    dense_p2g,
    g2p_explicit,
    p2g_with_forces,
)
from bfemp.state import State
from bfemp.steppers._buffers import BufferPool
from bfemp.steppers.base import ContactView, StepError, StepperOptions, StepReport
from bfemp.steppers.grid_step import GridStep, Motion
from bfemp.steppers.stable_dt import StableStep, stable_time_step
from bfemp.terms import ElasticityTerm, StepContext, fem_elastic_groups
from geometry.grid import particle_stencils

__all__ = ["ExplicitOptions", "ExplicitStepper", "GridStep", "Motion"]


#: particles per chunk of the parallel P2G (fixed, so results do not depend on the thread count)
P2G_CHUNK = 2048
#: cap of the number of P2G chunks
P2G_MAX_CHUNKS = 32


#: the CFL fractions are trade-study knobs (``StepperOptions``' ``sweep`` metadata): finer when
#: smaller, a factor 2 apart, at most 1
_CFL_SWEEP = {"finer": -1, "factor": 2.0, "max": 1.0}


@dataclass(frozen=True, kw_only=True)
class ExplicitOptions(StepperOptions):
    """Options every explicit strategy has.

    Attributes:
        cfl_safety_fem: safety factor on the FEM bound h_min / c_p, in (0, 1].
        cfl_safety_mpm: safety factor on the MPM bound ``dx / (c_p + |v_p|)``, in (0, 1].
    """

    strategy: ClassVar[str] = "explicit"

    cfl_safety_fem: float = field(default=0.5, metadata={"sweep": _CFL_SWEEP})
    cfl_safety_mpm: float = field(default=0.4, metadata={"sweep": _CFL_SWEEP})

    def __post_init__(self) -> None:
        self.check_numbers("cfl_safety_fem", "cfl_safety_mpm", high=1.0, what="a safety factor")


class ExplicitStepper:
    """The explicit engine (see the module docstring); strategies subclass it.

    Args:
        model: the static model.
        integrator: ``"symplectic_euler"`` (the only explicit integrator) or its object.
        dt: time step in s, or ``"auto"`` for the stable bound of the initial state.
        transfer: ``"apic"``, ``"pic"`` or ``"flip"`` (``transfers``; None: ``default_transfer``).
        options: the strategy's options (``Options()`` when None).
    """

    name: ClassVar[str] = "explicit"
    Options: ClassVar[type[StepperOptions]] = ExplicitOptions
    explicit: ClassVar[bool] = True
    #: the integrator ``Simulation`` takes when none is given
    default_integrator: ClassVar[str] = "symplectic_euler"
    #: the transfers the strategy takes, the one taken when none is given, and why others are not
    transfers: ClassVar[tuple[str, ...]] = SCHEMES
    default_transfer: ClassVar[str] = "apic"
    transfer_note: ClassVar[str] = ""
    #: 2D scenes take the dense-box kernels (``_dense2d_kernels``); False forces the general path
    dense_2d: ClassVar[bool] = True

    def __init__(
        self,
        model: Model,
        *,
        integrator: str | ExplicitIntegrator = "symplectic_euler",
        dt: float | str,
        transfer: str | None = None,
        options: StepperOptions | None = None,
    ) -> None:
        self.model = model
        self.integrator = integrator_from_name(integrator)
        if not getattr(self.integrator, "explicit", False):
            raise ValueError(
                f"strategy {self.name!r} is explicit: integrator must be "
                f"{SYMPLECTIC_EULER.name!r}, got {self.integrator.name!r} (an implicit integrator)"
            )
        transfer = self.default_transfer if transfer is None else transfer
        if transfer not in self.transfers:
            raise ValueError(
                f"{self.name}: transfer must be one of {self.transfers}, got {transfer!r}"
                + self.transfer_note
            )
        self.transfer = transfer
        options = self.Options() if options is None else options
        if not isinstance(options, self.Options):
            raise ValueError(
                f"{self.name}: options must be {self.Options.__name__}, "
                f"got {type(options).__name__}"
            )
        self.options = options
        bound = self.auto_dt_bound(model, model.initial_state(), options)
        if isinstance(dt, str):
            if dt != "auto":
                raise ValueError(
                    f"{self.name}: dt must be a number of seconds or 'auto', got {dt!r}"
                )
            if not math.isfinite(bound.dt):
                raise ValueError(f"{self.name}: dt='auto' needs a body to bound it")
            dt = bound.dt
        if (
            isinstance(dt, bool)
            or not isinstance(dt, int | float)
            or not (math.isfinite(dt) and dt > 0.0)
        ):
            raise ValueError(f"{self.name}: dt must be a positive number of seconds, got {dt!r}")
        if dt > bound.dt:
            raise ValueError(
                f"{self.name}: dt = {dt:.6g} s exceeds the explicit stable step "
                f"{bound.describe()}; take dt <= {bound.dt:.6g} s or dt='auto'"
            )
        self.dt = float(dt)
        self._build_forces()
        self._last_contact: ContactView | None = None
        self._setup()

    def _setup(self) -> None:
        """A strategy's own construction, after the engine's (default: nothing)."""

    # ------------------------------------------------------------------ construction
    @classmethod
    def auto_dt_bound(
        cls, model: Model, state: State, options: StepperOptions | None = None
    ) -> StableStep:
        """The stable step of ``state`` under ``options``' safety factors, and who sets it."""
        options = cls.Options() if options is None else options
        safety = {"fem_safety": options.cfl_safety_fem, "mpm_safety": options.cfl_safety_mpm}
        return stable_time_step(model, state, **safety)

    @classmethod
    def auto_dt(cls, model: Model, state: State | None = None, options: object = None) -> float:
        """The step ``dt="auto"`` takes, in s (``Simulation`` may ask before constructing)."""
        state = model.initial_state() if state is None else state
        return cls.auto_dt_bound(model, state, options).dt

    def _build_forces(self) -> None:
        model, d = self.model, self.model.dim
        self._fem_terms = [
            ElasticityTerm(law, stencils, name=f"elasticity[{law.name}]")
            for law, stencils in fem_elastic_groups(model)
        ]
        if model.n_fem_nodes:
            layout = DofLayout(d, np.ones(model.n_fem_nodes, dtype=bool), model.n_fem_nodes)
            ctx = StepContext(
                model=model,
                state=model.initial_state(),
                dt=self.dt,
                layout=layout,
                fixed_positions=model.fem_X,
                x_hat=np.zeros(layout.n_dof),
                dof_mass=np.repeat(model.fem_mass, d),
            )
            for term in self._fem_terms:
                term.begin_step(ctx)
            self._fem_free = ~model.fem_prescribed
            self._fem_inv_mass = _inverse(model.fem_mass)
        # MPM: per-particle Lame parameters and the particles of each law
        self._mpm_laws = []
        self._n_chunks = min(P2G_MAX_CHUNKS, max(1, model.n_particles // P2G_CHUNK))
        #: particle-sized output and work arrays, reused once nothing else holds them
        self._pool = BufferPool()
        if model.n_particles:
            owner = model.mpm_particle_body
            self._mpm_mu = np.array([b.material.mu for b in model.mpm_bodies])[owner]
            self._mpm_lam = np.array([b.material.lam for b in model.mpm_bodies])[owner]
            laws = {id(b.material.law): b.material.law for b in model.mpm_bodies}
            for law in laws.values():
                bodies = [b.index for b in model.mpm_bodies if b.material.law is law]
                particles = np.flatnonzero(np.isin(owner, bodies))
                whole = particles.size == model.n_particles
                self._mpm_laws.append((law, None if whole else particles))
        self._term_names = [
            *(t.name for t in self._fem_terms),
            *(f"mpm_elasticity[{law.name}]" for law, _ in self._mpm_laws),
            *(["gravity"] if model.has_gravity else []),
            *(["external_force"] if model.has_load else []),
        ]

    # ------------------------------------------------------------------ protocol
    @property
    def terms(self) -> list[str]:
        """Names of the force terms (elasticity per law, gravity, loads)."""
        return list(self._term_names)

    def initialize(self, state: State) -> State:
        """Nothing to start: symplectic Euler needs no a^0 (a copy of ``state``)."""
        return state.copy()

    def stable_dt(self, state: State) -> float:
        """The stable step of ``state`` in s (safety factors of the options included)."""
        return self.auto_dt_bound(self.model, state, self.options).dt

    def contact(self) -> ContactView:
        """The contact view a strategy stored for the last step (``lr``); without one (the engine
        has no contact algorithm): zero forces, no pairs, NaN distance and energy."""
        if self._last_contact is None:
            m = self.model
            self._last_contact = ContactView.empty(m.n_fem_nodes, m.n_particles, m.dim)
        return self._last_contact

    def checkpoint_data(self) -> dict[str, np.ndarray]:
        """No carried state beyond ``State``."""
        return {}

    def restore_checkpoint_data(self, data: object) -> None:
        """Nothing to restore."""

    # ------------------------------------------------------------------ phases
    def after_p2g(self, step: GridStep) -> None:
        """Correct the transferred grid fields in place (default: nothing; lr: its contact
        detection and first correction)."""

    def resolve(
        self, step: GridStep, grid_v: np.ndarray, fem_v: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Contact correction of the updated velocities v* ``(M, G, d)``, ``(N, d)`` in m/s
        (default: none)."""
        return grid_v, fem_v

    def g2p(self, step: GridStep, grid_v: np.ndarray) -> tuple[np.ndarray, ...]:
        """The particle update from the end velocities ``grid_v (M, G, d)`` m/s: ``(mpm_x,
        mpm_v, mpm_F, mpm_C)`` (default: the engine's G2P of its one field, module docstring
        step 5)."""
        state = step.state
        moving = (step.velocity[0], grid_v[0], self.dt, state.mpm_x, state.mpm_v, state.mpm_F)
        if step._box is not None:
            box = step._box
            return dense_g2p(box, self.model.grid.dx, self.transfer, *moving, self._pool.empty)
        st = step.stencils()
        stencil = (st.nodes, st.weights, st.grads, st.active_x)
        return g2p_explicit(self.transfer, *stencil, *moving, self._n_chunks, self._pool.empty)

    def after_g2p(self, step: GridStep, motion: Motion) -> None:
        """Correct the end-of-step values in place before they are committed (default:
        nothing)."""

    # ------------------------------------------------------------------ the step
    def _check_cfl(self, state: State) -> tuple[str, ...]:
        bound = self.auto_dt_bound(self.model, state, self.options)
        # dt="auto" is the bound itself: the same bound recomputed may differ in the last bit
        if self.dt <= bound.dt * (1.0 + 1e-12):
            return ()
        if self.dt > bound.limit:
            raise StepError.failed(
                state.step + 1,
                state.t + self.dt,
                "CFL_VIOLATED",
                f"dt = {self.dt:.6g} s exceeds the CFL limit {bound.limit:.6g} s "
                f"(CFL number 1; stable step {bound.describe()})",
            )
        return (f"CFL_ABOVE_SAFETY: dt = {self.dt:.6g} s above the stable step {bound.describe()}",)

    def mpm_stresses(self, state: State) -> np.ndarray:
        """First Piola stresses P(F_p^n) ``(P, d, d)`` in Pa, law by law (for a P2G phase)."""
        F = state.mpm_F
        out = self._pool.empty(F.shape)
        if len(self._mpm_laws) == 1 and self._mpm_laws[0][1] is None:
            return self._mpm_laws[0][0].first_piola(F, self._mpm_mu, self._mpm_lam, out=out)
        for law, idx in self._mpm_laws:
            out[idx] = law.first_piola(F[idx], self._mpm_mu[idx], self._mpm_lam[idx])
        return out

    def fem_forces(self, state: State) -> np.ndarray:
        """Internal + gravity + load forces on the FEM nodes ``(N, d)`` in N at x^n (for a P2G
        phase)."""
        model = self.model
        x = state.fem_x.reshape(-1)
        force = np.multiply.outer(model.fem_mass, model.gravity)
        for term in self._fem_terms:
            term.solution_changed(x)
            force -= term.gradient(x).reshape(-1, model.dim)
        if model.has_load:
            force += model.fem_load
        return force

    def particles_to_grid(self, state: State) -> GridStep:
        """Phase P2G: stencils, P2G of mass, momentum and forces; FEM forces (step 1)."""
        model, d = self.model, self.model.dim
        timings: dict[str, float] = {}
        stencils = box = None
        grid_mass = np.zeros(0)
        grid_x = grid_v = grid_force = np.zeros((0, d))
        if model.n_particles:
            started = time.perf_counter()
            piola = self.mpm_stresses(state)
            timings["stress"] = time.perf_counter() - started
            started = time.perf_counter()
            apic_C = state.mpm_C if self.transfer == "apic" else None
            particles = (state.mpm_x, model.mpm_mass, state.mpm_v, apic_C, piola, state.mpm_F)
            particles += (model.mpm_volume, self._n_chunks)
            dense = None
            if d == 2 and self.dense_2d:
                origin = np.asarray(model.grid.origin)
                dense = dense_p2g(origin, model.grid.dx, *particles, self._pool.empty)
            if dense is not None:
                box, grid_mass, momentum, grid_force = dense
                grid_x = box.node_x
            else:
                stencils = particle_stencils(model.grid, state.mpm_x)
                grid_x = stencils.active_x
                grid_mass, momentum, grid_force = p2g_with_forces(
                    stencils.nodes, stencils.weights, stencils.grads, grid_x, *particles
                )
            grid_v = momentum * _inverse(grid_mass)[:, None]
            grid_force += np.multiply.outer(grid_mass, model.gravity)
            timings["p2g"] = time.perf_counter() - started
        started = time.perf_counter()
        fem_force = self.fem_forces(state) if model.n_fem_nodes else np.zeros((0, d))
        timings["fem_forces"] = time.perf_counter() - started
        return GridStep(
            state=state,
            t_next=state.t + self.dt,
            dt=self.dt,
            grid_x=grid_x,
            mass=grid_mass[None],
            velocity=grid_v[None],
            force=grid_force[None],
            fem_force=fem_force,
            timings=timings,
            _stencils=stencils,
            _box=box,
            _grid=model.grid,
        )

    def _constrain(self, step: GridStep, grid_v: np.ndarray) -> np.ndarray:
        """Level-set constraints on v* ``(M, G, d)`` (step 4; decided here on v* unless a phase
        decided them already); the reactions go to ``step.boundary_forces``."""
        model = self.model
        if not model.boundaries or step.grid_x.shape[0] == 0:
            return grid_v
        if step.constraints is None:
            step.constraints = material_constraints(
                model.boundaries, step.grid_x, grid_v, step.t_next, step.dt
            )
        cons = step.constraints
        v = cons.apply(grid_v, step.dt)
        step.boundary_forces = cons.reactions(step.mass, grid_v, v, step.dt, len(model.boundaries))
        return v

    def _free_motion(self, step: GridStep) -> tuple[np.ndarray, np.ndarray]:
        """v* = v + dt M^-1 f of the grid ``(M, G, d)`` and FEM nodes ``(N, d)`` in m/s (step
        2)."""
        model, dt, integ = self.model, self.dt, self.integrator
        grid_a = step.force * _inverse(step.mass)[..., None]
        grid_v = integ.velocity(step.velocity, grid_a, dt)
        fem_v = np.zeros((0, model.dim))
        if model.n_fem_nodes:
            fem_a = step.fem_force * self._fem_inv_mass[:, None]
            fem_v = integ.velocity(step.state.fem_v, fem_a, dt)
            self._script_velocities(step, fem_v)
        return grid_v, fem_v

    def _script_velocities(self, step: GridStep, fem_v: np.ndarray) -> None:
        scripted = ~self._fem_free
        fem_v[scripted] = self.model.prescribed_velocities(step.t_next)[scripted]

    def _motion(self, step: GridStep, grid_v: np.ndarray, fem_v: np.ndarray) -> Motion:
        """FEM x += dt v (scripted nodes: their script) and the particle update (step 6)."""
        model, state = self.model, step.state
        t0 = time.perf_counter()
        fem_x = state.fem_x
        if model.n_fem_nodes:
            self._script_velocities(step, fem_v)
            fem_x = self.integrator.position(state.fem_x, fem_v, self.dt)
            scripted = ~self._fem_free
            fem_x[scripted] = model.prescribed_positions(step.t_next)[scripted]
        step.timings["update"] += time.perf_counter() - t0
        mpm = (state.mpm_x, state.mpm_v, state.mpm_F, state.mpm_C)
        if model.n_particles:
            t0 = time.perf_counter()
            mpm = self.g2p(step, grid_v)
            step.timings["g2p"] = time.perf_counter() - t0
        return Motion(fem_x, fem_v, *mpm)

    def step(self, state: State) -> tuple[State, StepReport]:
        """Advance ``state`` by dt (module docstring); ``StepError`` on a CFL violation."""
        started = time.perf_counter()
        notes = self._check_cfl(state)
        cfl = time.perf_counter() - started
        step = self.particles_to_grid(state)
        step.notes[:0], step.timings["cfl"] = notes, cfl
        self.after_p2g(step)
        t0 = time.perf_counter()
        grid_v, fem_v = self.resolve(step, *self._free_motion(step))
        grid_v = self._constrain(step, grid_v)
        step.timings["update"] = time.perf_counter() - t0
        motion = self._motion(step, grid_v, fem_v)
        self.after_g2p(step, motion)
        new = motion.commit(step)
        step.timings["step"] = time.perf_counter() - started
        return new, step.report()


def _inverse(mass: np.ndarray) -> np.ndarray:
    """1 / m ``(n,)`` in 1/kg, 0 on massless nodes."""
    out = np.zeros_like(mass)
    np.divide(1.0, mass, out=out, where=mass > 0.0)
    return out
