"""The value one explicit step hands from phase to phase (``GridStep``), and the end-of-step
values a step commits once (``Motion``); the engine is ``bfemp.steppers.explicit``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from bfemp.mpm.boundaries import GridConstraints
from bfemp.mpm.transfer import DenseBox
from bfemp.state import State
from bfemp.steppers.base import StepReport
from geometry.grid import Grid, ParticleStencils, particle_stencils

__all__ = ["GridStep", "Motion"]


@dataclass
class GridStep:
    """One explicit step's data, handed from phase to phase (arrays may be changed in place).

    Attributes:
        state: the start state at t^n (read only).
        t_next: end time t^{n+1} in s; ``dt`` in s.
        grid_x: positions x_i^n of the active grid nodes ``(G, d)`` in m (the active nodes and
            their order are those of ``particle_stencils``; ``stencils()`` gives the stencils).
        mass: node masses ``(M, G)`` in kg (kg/m in 2D), one row per velocity field (M = 1: the
            engine's one shared field).
        velocity: P2G node velocities v_i^n ``(M, G, d)`` in m/s.
        force: internal + gravity forces on the nodes ``(M, G, d)`` in N (N/m in 2D).
        fem_force: internal + gravity + load forces on the FEM nodes ``(N, d)`` in N.
        constraints: the level-set constraints applied to the grid (after ``resolve``).
        iterations, notes, timings, extra, status, message, boundary_forces: the step's
            report (``StepReport``'s fields of those names); ``outcome``: any other
            ``StepReport`` field by name (``residual``, ``min_distance``, ``contact_pairs``,
            ``friction_converged``); ``work``: a strategy's own arrays of the step, passed
            between its phases.
    """

    state: State
    t_next: float
    dt: float
    grid_x: np.ndarray
    mass: np.ndarray
    velocity: np.ndarray
    force: np.ndarray
    fem_force: np.ndarray
    constraints: GridConstraints | None = None
    iterations: dict[str, int] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)
    extra: dict[str, float] = field(default_factory=dict)
    status: str = "EXPLICIT"
    message: str = "explicit step"
    boundary_forces: tuple = ()
    outcome: dict[str, object] = field(default_factory=dict)
    work: dict[str, object] = field(default_factory=dict)
    _stencils: ParticleStencils | None = None
    _box: DenseBox | None = None
    _grid: Grid | None = None

    def stencils(self) -> ParticleStencils | None:
        """Particle stencils at x_p^n on the active nodes (built on first call in 2D, where the
        engine itself never stores them); None without particles."""
        if self._stencils is None and self.state.mpm_x.shape[0]:
            self._stencils = particle_stencils(self._grid, self.state.mpm_x)
        return self._stencils

    def report(self, **changes: object) -> StepReport:
        """The ``StepReport`` of the step (``changes``: fields to override, e.g. a failure's
        ``success``, ``status`` and ``message``)."""
        fields = dict(step=self.state.step + 1, t=self.t_next, success=True, status=self.status)
        fields.update(message=self.message, iterations=self.iterations, timings=self.timings)
        fields.update(boundary_forces=self.boundary_forces, notes=tuple(self.notes))
        return StepReport(**{**fields, "extra": self.extra, **self.outcome, **changes})


@dataclass
class Motion:
    """The end-of-step values of the moving points before they become the new ``State`` (the
    particle update's result; ``after_g2p`` may correct them): FEM node positions and
    velocities ``(N, d)`` in m, m/s; particle positions, velocities ``(P, d)``, deformation
    gradients and APIC matrices ``(P, d, d)``; ``carried``: the new arrays of ``State.carried``
    by name (the others carry over)."""

    fem_x: np.ndarray
    fem_v: np.ndarray
    mpm_x: np.ndarray
    mpm_v: np.ndarray
    mpm_F: np.ndarray
    mpm_C: np.ndarray
    carried: dict[str, np.ndarray] = field(default_factory=dict)

    def commit(self, step: GridStep) -> State:
        """The state at t^{n+1}: the one place a step writes positions."""
        start = step.state
        values = {"carried": {**start.carried, **self.carried}}  # a new dict: never shared
        if start.fem_x.shape[0]:
            values.update(
                fem_x=self.fem_x, fem_v=self.fem_v, fem_a=(self.fem_v - start.fem_v) / step.dt
            )
        if start.mpm_x.shape[0]:
            values.update(mpm_x=self.mpm_x, mpm_v=self.mpm_v, mpm_F=self.mpm_F, mpm_C=self.mpm_C)
        return replace(start, t=step.t_next, step=start.step + 1, **values)
