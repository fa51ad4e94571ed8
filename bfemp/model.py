"""The static part of a simulation: rest shapes, lumped masses, materials, boundary conditions.

A ``Model`` is built by ``Scene.build()``. FEM bodies are concatenated into global node and cell
arrays; each body keeps its slices so that a ``FemBody`` handle can read its part of a ``State``.

FEM discretisation (BFEMP paper section 3.1): linear simplices, F = Ds Dm^-1 (BFEMP eq. 24), so
F = sum_a x_a grad(N_a)^T with constant shape-function gradients; lumped masses rho V / (d + 1)
per vertex of every cell.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bfemp.motion import Motion
from bfemp.state import State
from geometry.grid import Grid

__all__ = ["Boundary", "FemBody", "Model", "MpmBody", "simplex_shape_gradients"]

#: Level-set boundary kinds on MPM grid nodes.
BOUNDARY_KINDS = ("sticky", "slip", "separate")


@dataclass(frozen=True, eq=False)
class FemBody:
    """Handle of one FEM body: its name, material, motion and slices of the global arrays."""

    name: str
    index: int
    material: object
    nodes: slice
    cells: slice
    prescribed_motion: Motion | None
    boundary: np.ndarray  # (k, d) global node indices of its boundary edges (2D) / faces (3D)

    def __index__(self) -> int:
        """The body's index, so a handle works wherever an index is expected."""
        return self.index

    def __repr__(self) -> str:
        """One line: name, index, node and cell ranges, material, motion, boundary size (not
        the boundary array itself)."""
        motion = type(self.prescribed_motion).__name__ if self.prescribed_motion else None
        facets = "edges" if self.boundary.ndim == 2 and self.boundary.shape[1] == 2 else "faces"
        return (
            f"FemBody(name={self.name!r}, index={self.index}, nodes={self.nodes.start}:"
            f"{self.nodes.stop}, cells={self.cells.start}:{self.cells.stop}, "
            f"material={type(self.material).__name__}, prescribed_motion={motion}, "
            f"boundary={self.boundary.shape[0]} {facets})"
        )

    @property
    def n_nodes(self) -> int:
        """Number of nodes of this body."""
        return self.nodes.stop - self.nodes.start

    def x(self, state: State) -> np.ndarray:
        """This body's node positions ``(n, d)`` in m (a view into ``state.fem_x``)."""
        return state.fem_x[self.nodes]

    def v(self, state: State) -> np.ndarray:
        """This body's node velocities ``(n, d)`` in m/s (a view into ``state.fem_v``)."""
        return state.fem_v[self.nodes]


@dataclass(frozen=True)
class MpmBody:
    """Handle of one MPM body: its name, material and slice of the particle arrays."""

    name: str
    index: int
    material: object
    particles: slice

    def __index__(self) -> int:
        """The body's index, so a handle works wherever an index is expected."""
        return self.index

    @property
    def n_particles(self) -> int:
        """Number of particles of this body."""
        return self.particles.stop - self.particles.start

    def x(self, state: State) -> np.ndarray:
        """This body's particle positions ``(p, d)`` in m (a view into ``state.mpm_x``)."""
        return state.mpm_x[self.particles]

    def v(self, state: State) -> np.ndarray:
        """This body's particle velocities ``(p, d)`` in m/s (a view into ``state.mpm_v``)."""
        return state.mpm_v[self.particles]


@dataclass(frozen=True)
class Boundary:
    """A static level-set boundary acting on MPM grid nodes inside it (value <= 0).

    ``kind``: ``"sticky"`` (no-slip: the node moves with the boundary), ``"slip"`` (no normal
    motion relative to the boundary, free tangential motion) or ``"separate"`` (slip while the
    node moves into the boundary, free when it moves away, decided per step from the transferred
    grid velocity). ``motion``: an optional translation of the level set (``bfemp.motion``
    Linear or a Sequence of Linear segments).
    """

    levelset: object
    kind: str
    motion: Motion | None = None


def simplex_shape_gradients(points: np.ndarray, cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gradients of the linear shape functions and rest volumes of simplices.

    Args:
        points: rest positions ``(N, d)`` in m.
        cells: vertex indices ``(M, d + 1)``.

    Returns:
        ``grad (M, d + 1, d)`` in 1/m, with F = sum_a x_a grad_a^T, and ``volume (M,)`` in m^d
        (signed: negative for inverted cells).
    """
    x = points[cells]  # (M, d+1, d)
    dm = np.swapaxes(x[:, 1:, :] - x[:, :1, :], 1, 2)  # (M, d, d), columns X_a - X_0
    det = np.linalg.det(dm)
    dim = points.shape[1]
    volume = det / (2.0 if dim == 2 else 6.0)
    dm_inv = np.linalg.inv(dm)  # rows are grad N_a, a = 1..d (BFEMP eq. 24: F = Ds Dm^-1)
    grad = np.empty((cells.shape[0], dim + 1, dim))
    grad[:, 1:, :] = dm_inv
    grad[:, 0, :] = -dm_inv.sum(axis=1)
    return grad, volume


@dataclass(frozen=True)
class Model:
    """Static description of a scene (built by ``Scene.build``).

    Attributes:
        dim: spatial dimension, 2 (plane strain, per unit thickness) or 3.
        gravity: gravitational acceleration ``(d,)`` in m/s^2.
        fem_X: rest (and initial) node positions ``(N, d)`` in m.
        fem_v0: initial node velocities ``(N, d)`` in m/s.
        fem_mass: lumped node masses ``(N,)`` in kg (per unit thickness in 2D).
        fem_cells: cell vertex indices ``(M, d + 1)`` (global).
        fem_cell_volume: rest volumes ``(M,)`` in m^d.
        fem_cell_grad: shape-function gradients ``(M, d + 1, d)`` in 1/m.
        fem_cell_body: body index of each cell ``(M,)``.
        fem_prescribed: whether each node is scripted ``(N,)`` bool.
        fem_bodies: the body handles, in insertion order.
        fem_load: constant external nodal forces ``(N, d)`` in N (N/m in 2D).
        mpm_X: initial particle positions ``(P, d)`` in m.
        mpm_v0: initial particle velocities ``(P, d)`` in m/s.
        mpm_volume: initial particle volumes ``(P,)`` in m^d.
        mpm_mass: particle masses ``(P,)`` in kg (per unit thickness in 2D).
        mpm_particle_body: body index of each particle ``(P,)``.
        mpm_bodies: the MPM body handles, in insertion order.
        grid: the MPM background grid (None when the scene has no particles).
        boundaries: level-set boundaries acting on grid nodes.
        contact: barrier/friction parameters (None: bodies do not interact through contact).
    """

    dim: int
    gravity: np.ndarray
    fem_X: np.ndarray
    fem_v0: np.ndarray
    fem_mass: np.ndarray
    fem_cells: np.ndarray
    fem_cell_volume: np.ndarray
    fem_cell_grad: np.ndarray
    fem_cell_body: np.ndarray
    fem_prescribed: np.ndarray
    fem_bodies: tuple[FemBody, ...]
    fem_load: np.ndarray
    mpm_X: np.ndarray
    mpm_v0: np.ndarray
    mpm_volume: np.ndarray
    mpm_mass: np.ndarray
    mpm_particle_body: np.ndarray
    mpm_bodies: tuple[MpmBody, ...]
    grid: Grid | None
    boundaries: tuple[Boundary, ...]
    contact: object | None = None

    @property
    def n_fem_nodes(self) -> int:
        """Number of FEM nodes over all bodies."""
        return self.fem_X.shape[0]

    @property
    def n_particles(self) -> int:
        """Number of MPM particles over all bodies."""
        return self.mpm_X.shape[0]

    @property
    def has_load(self) -> bool:
        """Whether any external nodal force is non-zero."""
        return bool(np.any(self.fem_load != 0.0))

    @property
    def has_gravity(self) -> bool:
        """Whether gravity is non-zero."""
        return bool(np.any(self.gravity != 0.0))

    def prescribed_positions(self, t: float) -> np.ndarray:
        """Positions ``(N, d)`` in m at time ``t`` s: scripted nodes moved, others at rest shape."""
        x = self.fem_X.copy()
        for body, mask in self._prescribed_sets():
            x[mask] = body.prescribed_motion.positions(self.fem_X[mask], t)
        return x

    def prescribed_velocities(self, t: float) -> np.ndarray:
        """Velocities ``(N, d)`` in m/s of scripted nodes at time ``t`` s (zero elsewhere)."""
        v = np.zeros_like(self.fem_X)
        for body, mask in self._prescribed_sets():
            v[mask] = body.prescribed_motion.velocities(self.fem_X[mask], t)
        return v

    def _prescribed_sets(self) -> list[tuple[FemBody, np.ndarray]]:
        out = []
        for body in self.fem_bodies:
            if body.prescribed_motion is None:
                continue
            mask = np.zeros(self.n_fem_nodes, dtype=bool)
            mask[body.nodes] = self.fem_prescribed[body.nodes]
            out.append((body, mask))
        return out

    def initial_state(self) -> State:
        """State at t = 0: rest positions, initial velocities, F = I, zero C and accelerations."""
        d, n_p = self.dim, self.n_particles
        return State(
            t=0.0,
            fem_x=self.fem_X.copy(),
            fem_v=self.fem_v0.copy(),
            fem_a=np.zeros_like(self.fem_X),
            mpm_x=self.mpm_X.copy(),
            mpm_v=self.mpm_v0.copy(),
            mpm_F=np.tile(np.eye(d), (n_p, 1, 1)),
            mpm_C=np.zeros((n_p, d, d)),
            mpm_a=np.zeros((n_p, d)),
            mpm_Ca=np.zeros((n_p, d, d)),
        )
