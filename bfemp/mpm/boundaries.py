"""Level-set boundaries on MPM grid nodes (sticky, slip, separate) as constraints of one step.

A grid node is constrained by a boundary when its start position x_i^n lies inside it
(``levelset.value(x_i^n) <= 0``); where several boundaries contain a node the deepest one (the
smallest value) acts.

- sticky: the node is not an unknown; it stays at x_i^n (zero velocity).
- slip: the node moves only tangentially: its motion along the boundary normal n is fixed to 0.
- separate: slip while the node moves into the boundary (v_i^n . n < 0, from the transferred
  grid velocity), free when it moves away; decided once per step.

Slip is imposed exactly by rotating the node's unknowns into the frame (n, t1[, t2]) and fixing
the normal coordinate (``NodeFrames``); explicit steps apply the constraints to velocities
(``GridConstraints.apply``), to velocity increments (``project``) and report the boundaries'
reactions (``reactions``). One grid may carry several velocity fields (one per material, the
``lr`` strategy): ``material_constraints`` gives one set for all of them, or one per field where a
separate boundary makes the sets differ.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["GridConstraints", "grid_constraints", "material_constraints", "normal_frames"]


@dataclass(frozen=True)
class GridConstraints:
    """Per active grid node: ``sticky (G,)``, ``slip (G,)`` bool, unit ``normals (G, d)``, the
    boundary's displacement over the step at the node ``shift (G, d)`` in m (zero for static
    boundaries) and the index of the acting boundary ``owner (G,)`` (-1: none).

    With a material axis (``material_constraints``) every array has a leading axis M, one set
    per velocity field; without one, the set serves every field.
    """

    sticky: np.ndarray
    slip: np.ndarray
    normals: np.ndarray
    shift: np.ndarray
    owner: np.ndarray

    @property
    def any(self) -> bool:
        """Whether any node is constrained."""
        return bool(self.sticky.any() or self.slip.any())

    @property
    def per_material(self) -> bool:
        """Whether the sets differ by field (a leading material axis)."""
        return self.sticky.ndim == 2

    def _sets(self, n_fields: int) -> list[tuple[object, GridConstraints]]:
        """(index of the fields, set) pairs: ``...`` and self when one set serves them all."""
        if not self.per_material:
            return [(..., self)]
        return [(m, GridConstraints(*(a[m] for a in self._arrays()))) for m in range(n_fields)]

    def _arrays(self) -> tuple[np.ndarray, ...]:
        return (self.sticky, self.slip, self.normals, self.shift, self.owner)

    def apply(self, v: np.ndarray, dt: float) -> np.ndarray:
        """Velocities ``(G, d)`` or ``(M, G, d)`` in m/s with the constraints imposed (a copy;
        ``v`` itself when nothing is constrained): sticky nodes take the boundary's velocity
        v_b = shift / dt, slip nodes lose the normal component of v - v_b."""
        if not self.any:
            return v
        v = v.copy()
        for m, c in self._sets(v.shape[0]):
            if not c.any:
                continue
            v_b = c.shift / dt
            field = v[m]
            field[..., c.sticky, :] = v_b[c.sticky]
            n = c.normals[c.slip]
            rel = np.einsum("...ij,ij->...i", field[..., c.slip, :] - v_b[c.slip], n)
            field[..., c.slip, :] -= rel[..., None] * n
        return v

    def project(self, u: np.ndarray) -> np.ndarray:
        """A velocity increment ``(G, d)`` or ``(M, G, d)`` in m/s with the prescribed
        components removed (in place; sticky: all, slip: the normal one)."""
        for m, c in self._sets(u.shape[0] if u.ndim == 3 else 1):
            if not c.any:
                continue
            field = u[m]
            field[..., c.sticky, :] = 0.0
            n = c.normals[c.slip]
            field[..., c.slip, :] -= (
                np.einsum("...ij,ij->...i", field[..., c.slip, :], n)[..., None] * n
            )
        return u

    def reactions(
        self,
        mass: np.ndarray,
        v_before: np.ndarray,
        v_after: np.ndarray,
        dt: float,
        n_boundaries: int,
    ) -> tuple[tuple[float, ...], ...]:
        """Per boundary, the reaction force (d,) in N (N/m in 2D) of its nodes: the sum of
        m_i (v_after - v_before) / dt over every field; masses ``(G,)`` or ``(M, G)`` in kg,
        velocities ``(G, d)`` or ``(M, G, d)`` in m/s (the before/after of ``apply``)."""
        d = v_after.shape[-1]
        reaction = np.zeros((n_boundaries, d))
        if mass.ndim == 1:
            mass, v_before, v_after = mass[None], v_before[None], v_after[None]
        for m in range(mass.shape[0]):
            owner = self.owner[m] if self.per_material else self.owner
            touched = owner >= 0
            impulse = mass[m, touched, None] * (v_after[m, touched] - v_before[m, touched]) / dt
            np.add.at(reaction, owner[touched], impulse)
        return tuple(tuple(float(c) for c in row) for row in reaction)


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


def material_constraints(
    boundaries: tuple, grid_x: np.ndarray, v: np.ndarray, t_next: float, dt: float
) -> GridConstraints:
    """The constraints of M velocity fields ``v (M, G, d)`` m/s on one grid ``(G, d)`` m: one set
    when no boundary is ``separate`` (sticky and slip nodes do not depend on the velocity), else
    one per field (a leading material axis)."""
    if all(b.kind != "separate" for b in boundaries):
        return grid_constraints(boundaries, grid_x, v[0], t_next, dt)
    sets = [grid_constraints(boundaries, grid_x, v_m, t_next, dt) for v_m in v]
    return GridConstraints(
        *(np.stack(arrays) for arrays in zip(*(c._arrays() for c in sets), strict=True))
    )


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
