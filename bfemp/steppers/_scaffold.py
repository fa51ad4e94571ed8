"""The scaffolding every grid-based step shares: gather all-node fields, write the new state.

A step works on "all nodes": the FEM nodes ``[0, N)`` then the active MPM grid nodes of the step
``[N, N + G)`` (``bfemp.dofs``): ``nodes_of_step`` (after the P2G, Tables 1-3) and
``write_state`` (one G2P) convert between those and ``State``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from bfemp.contact.friction import FrictionTerm
from bfemp.contact.term import BarrierTerm
from bfemp.dofs import DofLayout
from bfemp.frames import NodeFrames
from bfemp.model import Model
from bfemp.mpm.boundaries import normal_frames
from bfemp.mpm.step import MpmStep
from bfemp.mpm.transfer import grid_to_particles
from bfemp.potential import IncrementalPotential
from bfemp.state import State
from bfemp.terms import StepContext
from solvers.linear import LinearSolver

__all__ = ["StepNodes", "StepPhases", "nodes_of_step", "write_state"]


@dataclass(frozen=True)
class StepNodes:
    """Every node's fields at the start of a step from t^n to ``t_next``.

    Attributes:
        t_next: end time of the step in s.
        dt: step length in s.
        layout: free nodes (unknowns): free FEM nodes and grid nodes that are not sticky.
        mpm: stencils, P2G fields and constraints of the step's grid (None without particles).
        x: positions ``(n_all, d)`` in m at t^n (grid nodes: their start positions).
        v: velocities ``(n_all, d)`` in m/s (grid: P2G).
        a: accelerations ``(n_all, d)`` in m/s^2 (grid: P2G for Newmark, else zero).
        mass: lumped masses ``(n_all,)`` in kg (kg/m in 2D).
        fixed: end positions ``(n_all, d)`` in m of scripted nodes (FEM: their motion at
            ``t_next``; grid: start position plus the boundary's shift); free entries unused.
        shift: ``(n_all, d)`` in m, how far each node's level-set boundary moves over the step
            (zero for FEM nodes and without moving boundaries).
        frames: rotated frames of the slip nodes among the unknowns, None without any.
    """

    t_next: float
    dt: float
    layout: DofLayout
    mpm: MpmStep | None
    x: np.ndarray
    v: np.ndarray
    a: np.ndarray
    mass: np.ndarray
    fixed: np.ndarray
    shift: np.ndarray
    frames: NodeFrames | None

    def start(self) -> np.ndarray:
        """Start positions of the unknowns ``(n_dof,)`` in m: x^n, with nodes on moving slip
        boundaries moved along with them (their normal coordinate is fixed there)."""
        x_n = self.layout.restrict(self.x)
        if self.mpm is not None and self.mpm.constraints.shift.any():
            return x_n + self.layout.restrict(self.shift)
        return x_n

    def context(self, model: Model, state: State, x_hat_all: np.ndarray) -> StepContext:
        """The terms' view of the step, predicting the all-node positions ``x_hat_all (n_all,
        d)`` in m (BFEMP eq. 22's x_hat; two_stage: the free motion x*)."""
        layout = self.layout
        return StepContext(
            model=model,
            state=state,
            dt=self.dt,
            layout=layout,
            fixed_positions=self.fixed,
            x_hat=layout.restrict(x_hat_all),
            dof_mass=np.repeat(self.mass[layout.free_nodes], model.dim),
            mpm=self.mpm,
        )


@dataclass(frozen=True)
class StepPhases:
    """A begun, untaken ``barrier`` step (``BarrierStepper.phases``), for inspection.

    Attributes:
        potential: the step's incremental potential E(y) (BFEMP eq. 22) in J (J/m in 2D), begun
            for the step; its unknowns y = ``potential.to_unknowns(x)``.
        context: the terms' view of the step (``StepContext``: layout, x_hat ``(n_dof,)`` in
            m, DOF masses, MPM stencils, fixed positions).
        x0: the unknowns' positions at t^n ``(n_dof,)`` in m, node-major.
        barrier: the potential's barrier term (BFEMP eq. 27), None without contact.
        friction: its lagged friction term (BFEMP eq. 37), None without friction.
        linear_solver: the Newton loop's linear solver.
    """

    potential: IncrementalPotential
    context: StepContext
    x0: np.ndarray
    barrier: BarrierTerm | None
    friction: FrictionTerm | None
    linear_solver: LinearSolver

    @property
    def layout(self) -> DofLayout:
        """The step's unknowns (free FEM nodes and unconstrained grid nodes)."""
        return self.context.layout


def nodes_of_step(
    model: Model, state: State, mpm: MpmStep | None, *, dt: float, t_next: float
) -> StepNodes:
    """All-node fields of a step whose grid part (stencils, P2G, constraints) is ``mpm`` (None
    without particles): the FEM nodes of ``state`` then the grid nodes (``barrier`` after its P2G,
    ``bfemp.mpm.step.prepare_mpm_step``; ``two_stage`` with the explicit engine's P2G)."""
    d, n_fem = model.dim, model.n_fem_nodes
    fem_fixed = model.prescribed_positions(t_next)
    fem = (state.fem_x, state.fem_v, state.fem_a, model.fem_mass, fem_fixed, np.zeros((n_fem, d)))
    if mpm is None:
        layout = DofLayout(d, ~model.fem_prescribed, n_fem)
        return StepNodes(t_next, dt, layout, None, *fem, None)
    grid_x, shift = mpm.stencils.active_x, mpm.constraints.shift
    grid_a = mpm.acceleration if mpm.acceleration is not None else 0.0 * grid_x
    grid = (grid_x, mpm.fields.velocity, grid_a, mpm.fields.mass, grid_x + shift, shift)
    layout = DofLayout(d, np.concatenate([~model.fem_prescribed, ~mpm.constraints.sticky]), n_fem)
    all_nodes = map(np.concatenate, zip(fem, grid, strict=True))  # x, v, a, mass, fixed, shift
    return StepNodes(t_next, dt, layout, mpm, *all_nodes, _slip_frames(layout, mpm))


def _slip_frames(layout: DofLayout, mpm: MpmStep) -> NodeFrames | None:
    """Rotated frames (normal first) of the slip grid nodes among the unknowns."""
    if not mpm.constraints.slip.any():
        return None
    slip_nodes = np.flatnonzero(mpm.constraints.slip)
    dof_nodes = layout.dof_node[slip_nodes + mpm.node_offset]
    keep = dof_nodes >= 0
    return NodeFrames(
        layout.dim,
        layout.n_dof,
        dof_nodes[keep],
        normal_frames(mpm.constraints.normals[slip_nodes[keep]]),
    )


def write_state(
    model: Model,
    state: State,
    nodes: StepNodes,
    *,
    transfer: str,
    x_end: np.ndarray,
    v_end: np.ndarray,
    a_end: np.ndarray,
) -> State:
    """The state at ``nodes.t_next`` from every node's end-of-step fields.

    Args:
        model: the static model.
        state: the state at t^n.
        nodes: the step's start fields (``nodes_of_step``).
        transfer: ``"apic"``, ``"pic"`` or ``"flip"``.
        x_end: end positions ``(n_all, d)`` in m.
        v_end: end velocities ``(n_all, d)`` in m/s (sticky grid nodes are set here to ride
            their boundary).
        a_end: end accelerations ``(n_all, d)`` in m/s^2.
    """
    n_fem, dt, t_next = model.n_fem_nodes, nodes.dt, nodes.t_next
    mpm = nodes.mpm
    if mpm is not None and mpm.constraints.sticky.any():  # sticky nodes ride the boundary
        sticky = np.flatnonzero(mpm.constraints.sticky)
        v_end[n_fem + sticky] = mpm.constraints.shift[sticky] / dt
    prescribed = model.fem_prescribed
    v_scripted = model.prescribed_velocities(t_next)
    fem_a = a_end[:n_fem].copy()
    fem_a[prescribed] = (v_scripted[prescribed] - state.fem_v[prescribed]) / dt
    new = replace(
        state,
        t=t_next,
        step=state.step + 1,
        fem_x=x_end[:n_fem].copy(),
        fem_v=np.where(prescribed[:, None], v_scripted, v_end[:n_fem]),
        fem_a=fem_a,
        carried={},
    )
    if mpm is None:
        return new
    st = mpm.stencils
    with_a = mpm.acceleration is not None
    grid = (st.nodes, st.weights, st.grads, st.active_x, x_end[n_fem:], mpm.fields.velocity)
    update = grid_to_particles(
        transfer,
        *grid,
        v_end[n_fem:],
        a_end[n_fem:] if with_a else None,
        state.mpm_x,
        state.mpm_v,
        state.mpm_F,
        grid_a_old=mpm.acceleration if with_a else None,
        mpm_a=state.mpm_a if with_a else None,
    )
    new.mpm_x, new.mpm_v, new.mpm_F, new.mpm_C = update[:4]
    if with_a:  # a^{n+1} crosses back like the velocity (FLIP increments, APIC affine)
        new.mpm_a, new.mpm_Ca = update.mpm_a, update.mpm_Ca
    return new
