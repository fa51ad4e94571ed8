"""Level-set boundaries on MPM grid nodes (sticky, slip, separate) as constraints of one step.

A grid node is constrained by a boundary when its start position x_i^n lies inside it
(``levelset.value(x_i^n) <= 0``); where several boundaries contain a node the deepest one (the
smallest value) acts.

- sticky: the node is not an unknown; it stays at x_i^n (zero velocity).
- slip: the node moves only tangentially: its motion along the boundary normal n is fixed to 0.
- separate: slip while the node moves into the boundary (v_i^n . n < 0, from the transferred
  grid velocity), free when it moves away; decided once per step.

Slip is imposed exactly by rotating the node's unknowns into the frame (n, t1[, t2]) and fixing
the normal coordinate (``NodeFrames``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["GridConstraints", "grid_constraints", "normal_frames"]


@dataclass(frozen=True)
class GridConstraints:
    """Per active grid node: ``sticky (G,)``, ``slip (G,)`` bool, unit ``normals (G, d)``, the
    boundary's displacement over the step at the node ``shift (G, d)`` in m (zero for static
    boundaries) and the index of the acting boundary ``owner (G,)`` (-1: none)."""

    sticky: np.ndarray
    slip: np.ndarray
    normals: np.ndarray
    shift: np.ndarray
    owner: np.ndarray

    @property
    def any(self) -> bool:
        """Whether any node is constrained."""
        return bool(self.sticky.any() or self.slip.any())


def _translation(boundary: object, t: float, d: int) -> tuple[np.ndarray, np.ndarray]:
    """Displacement (d,) in m and velocity (d,) in m/s of a moving level set at time t."""
    if boundary.motion is None:
        return np.zeros(d), np.zeros(d)
    origin = np.zeros((1, d))
    return boundary.motion.positions(origin, t)[0], boundary.motion.velocities(origin, t)[0]


def grid_constraints(
    boundaries: tuple,
    grid_x: np.ndarray,
    grid_v: np.ndarray,
    t_next: float = 0.0,
    dt: float = 0.0,
) -> GridConstraints:
    """Constraints of the active grid nodes at positions ``(G, d)`` m with velocities ``(G, d)``.

    Moving boundaries are evaluated where they are at the end of the step, ``t_next`` s, and
    carry their nodes along by their displacement over the step (``dt`` s).
    """
    n, d = grid_x.shape
    sticky = np.zeros(n, dtype=bool)
    slip = np.zeros(n, dtype=bool)
    normals = np.zeros((n, d))
    shift = np.zeros((n, d))
    owner = np.full(n, -1, dtype=np.int64)
    if not boundaries or n == 0:
        return GridConstraints(sticky, slip, normals, shift, owner)
    depth = np.full(n, np.inf)
    moved = []
    for k, boundary in enumerate(boundaries):  # a handful of boundaries, vectorised over nodes
        disp_next, vel = _translation(boundary, t_next, d)
        local = grid_x - disp_next  # the node in the boundary's own frame
        moved.append((local, vel))
        phi = np.asarray(boundary.levelset.value(local), dtype=np.float64)
        take = (phi <= 0.0) & (phi < depth)
        depth[take] = phi[take]
        owner[take] = k
    for k, boundary in enumerate(boundaries):
        mine = owner == k
        if not mine.any():
            continue
        local, vel = moved[k]
        shift[mine] = dt * vel
        if boundary.kind == "sticky":
            sticky |= mine
            continue
        nrm = np.asarray(boundary.levelset.normal(local[mine]), dtype=np.float64)
        active = np.ones(nrm.shape[0], dtype=bool)
        if boundary.kind == "separate":
            active = np.einsum("ij,ij->i", grid_v[mine] - vel, nrm) < 0.0
        idx = np.flatnonzero(mine)
        released = idx[~active]
        owner[released] = -1
        shift[released] = 0.0
        slip[idx[active]] = True
        normals[idx[active]] = nrm[active]
    return GridConstraints(sticky, slip, normals, shift, owner)


def normal_frames(normals: np.ndarray) -> np.ndarray:
    """Orthonormal frames ``(n, d, d)`` whose first column is the unit normal ``(n, d)``."""
    n, d = normals.shape
    frames = np.zeros((n, d, d))
    nrm = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    frames[:, :, 0] = nrm
    if d == 2:
        frames[:, 0, 1] = -nrm[:, 1]
        frames[:, 1, 1] = nrm[:, 0]
        return frames
    # a helper axis far from the normal, then Gram-Schmidt
    helper = np.zeros((n, 3))
    helper[np.arange(n), np.argmin(np.abs(nrm), axis=1)] = 1.0
    t1 = np.cross(nrm, helper)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    frames[:, :, 1] = t1
    frames[:, :, 2] = np.cross(nrm, t1)
    return frames
