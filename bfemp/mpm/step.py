"""The MPM part of one implicit step: stencils at x^n, P2G, grid constraints (Algorithm 1 line 2).

Grid node g of this step is node ``node_offset + g`` in the all-nodes numbering of ``DofLayout``
(FEM nodes first).

Newmark needs a^n on the grid. It is transferred exactly the way the velocity is: with APIC the
particles carry an affine acceleration matrix ``mpm_Ca`` beside ``mpm_C`` (so an affine
acceleration field, e.g. the centripetal one of a rigid rotation, crosses the transfers intact);
with FLIP the particle acceleration is updated by the grid increment; with PIC it is interpolated.
A smoothed (PIC-only) acceleration would feed a projection error of O(dt |a|) into every step's
velocity update, an O(1) drift over a fixed time that refining dt does not remove.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from bfemp.model import Model
from bfemp.mpm.boundaries import GridConstraints, grid_constraints
from bfemp.mpm.transfer import GridFields, particles_to_grid
from bfemp.state import State
from geometry.grid import ParticleStencils, particle_stencils

__all__ = ["LIGHT_NODE_REL", "MpmStep", "constrained_mpm_step", "prepare_mpm_step"]

#: Grid nodes lighter than this fraction of the heaviest node are pinned (no unknowns): only
#: round-off weights (~1e-33) fall below it; real light nodes stay unknowns, since pinning them
#: drops their share of the elastic force and leaks momentum (measured 1.6e-7 at 1e-10).
LIGHT_NODE_REL = 1e-20


@dataclass(frozen=True)
class MpmStep:
    """Stencils, transferred grid fields and constraints of the active grid of one step."""

    stencils: ParticleStencils
    fields: GridFields
    constraints: GridConstraints
    node_offset: int
    acceleration: np.ndarray | None  # (G, d) a_i^n for Newmark

    @property
    def n_nodes(self) -> int:
        """Number of active grid nodes G."""
        return self.stencils.n_nodes


def prepare_mpm_step(
    model: Model,
    state: State,
    transfer: str,
    with_acceleration: bool,
    dt: float = 0.0,
) -> MpmStep:
    """Quadratic B-spline stencils of the particles at x^n, P2G (Tables 1-3), constraints."""
    stencils = particle_stencils(model.grid, state.mpm_x)
    apic = transfer == "apic"
    fields = particles_to_grid(
        transfer,
        stencils.nodes,
        stencils.weights,
        stencils.active_x,
        state.mpm_x,
        model.mpm_mass,
        state.mpm_v,
        state.mpm_C if apic else None,
        state.mpm_a if with_acceleration else None,
        mpm_Ca=state.mpm_Ca if apic and with_acceleration else None,
    )
    return constrained_mpm_step(model, stencils, fields, fields.velocity, state.t + dt, dt)


def constrained_mpm_step(
    model: Model, stencils: ParticleStencils, fields: GridFields, v: np.ndarray, t: float, dt: float
) -> MpmStep:
    """The step's grid with its level-set constraints decided on ``v (G, d)`` in m/s (P2G's,
    or ``two_stage``'s free motion v*) for the step of ``dt`` s to ``t``."""
    constraints = grid_constraints(model.boundaries, stencils.active_x, v, t, dt)
    # Nodes that only round-off weights reach (a particle exactly on a cell-centre line gets
    # w ~ 1e-33 for the far node) carry no mass and no stiffness: as unknowns they would make
    # the Newton system singular. Pin them where they are; the particles do not feel them.
    light = fields.mass < LIGHT_NODE_REL * fields.mass.max()
    if light.any():
        constraints = replace(constraints, sticky=constraints.sticky | light)
    return MpmStep(stencils, fields, constraints, model.n_fem_nodes, fields.acceleration)
