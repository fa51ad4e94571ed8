"""The end-state half of the intersection check: points strictly inside another FEM body.

Every FEM node, particle and FEM cell centroid is tested against the cells of every other FEM
body (:func:`geometry.inside.simplex_depth`, strict convention); see
:mod:`bfemp.contact.intersection`.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from bfemp.contact.collision import CollisionSet, PointStencils, build_collision_set
from bfemp.model import Model
from bfemp.state import State
from geometry.broadphase import point_simplex_candidates
from geometry.inside import simplex_depth

__all__ = ["Intersection", "cells_containing", "end_of_step_points", "points_inside"]

#: Strict inside test (geometry.inside's convention): every barycentric coordinate above this.
_BARY_EPS = 1e-12


@dataclass(frozen=True)
class Intersection:
    """The first crossing found in a step.

    Attributes:
        status: ``"INTERSECTION"`` (at the end of the step) or ``"TUNNELED"`` (along the
            step's straight-line motion).
        s: fraction of the step at which it was found (1.0 for the end state; for a crossing,
            the earliest time at which a pair came within the floor).
        n_points: number of points found inside another body (end state) or of points (edge
            pairs) crossing along the motion.
        point: ``"FEM node i of body 'A'"``, ``"particle i of body 'B'"``, ``"the centroid of
            cell i of body 'A'"`` (indices local to the body) or, in 3D, a boundary edge.
        body: name of the FEM body it lies in.
    """

    status: str
    s: float
    n_points: int
    point: str
    body: str

    @property
    def message(self) -> str:
        """Human-readable outcome for a step report."""
        if self.status == "TUNNELED":
            return (
                f"{self.n_points} point(s) or edge(s) pass into another FEM body along the step's "
                f"straight-line motion, first at {self.s:.3g} of the step: {self.point} reaches "
                f"the boundary of body {self.body!r} (the time step is too large for this "
                "collision; reduce dt)"
            )
        return (
            f"{self.n_points} point(s) inside another FEM body at the end of the step, e.g. "
            f"{self.point} inside body {self.body!r}"
        )


def points_inside(
    points: np.ndarray,
    point_body: np.ndarray,
    vertices: np.ndarray,
    cells: np.ndarray,
    cell_body: np.ndarray,
) -> np.ndarray:
    """The cell of another body that each point lies strictly inside, or -1.

    Args:
        points: ``(P, d)`` point positions in m.
        point_body: ``(P,)`` owning body of each point (FEM body index, or any value that no
            cell has, e.g. negative for particles).
        vertices: ``(V, d)`` cell vertex positions in m.
        cells: ``(C, d + 1)`` vertex indices of triangles (2D) / tetrahedra (3D).
        cell_body: ``(C,)`` FEM body index of each cell.

    Returns:
        ``(P,)`` int64: the smallest index of a containing cell of a body other than the
        point's own, -1 where there is none.
    """
    return cells_containing(points, point_body, vertices, cells, cell_body)[0]


def cells_containing(
    points: np.ndarray,
    point_body: np.ndarray,
    vertices: np.ndarray,
    cells: np.ndarray,
    cell_body: np.ndarray,
    tol: float = _BARY_EPS,
) -> tuple[np.ndarray, np.ndarray]:
    """For each point, the first cell of another body that contains it with every barycentric
    coordinate above ``tol``, and that depth.

    Arguments as :func:`points_inside`. Returns ``cell (P,)`` int64 (the smallest such cell
    index, -1 where none) and ``depth (P,)``: its smallest barycentric coordinate
    (dimensionless, 0 where none). Broad phase as the intersection check's: cost O(P + C + hits)
    where a test of every pair costs O(P C).
    """
    found = np.full(points.shape[0], -1, dtype=np.int64)
    depth = np.zeros(points.shape[0])
    # candidates of different bodies, unique and sorted by (point, cell) (the broad phase's order)
    cand = point_simplex_candidates(points, vertices, cells, groups=(point_body, cell_body))
    if cand.shape[0] == 0:  # no parallel region for nothing
        return found, depth
    cand_depth = _pair_depths(points, vertices, cells, cand)
    keep = cand_depth > tol
    hits, hit_depth = cand[keep], cand_depth[keep]
    if hits.shape[0]:
        first = np.concatenate(([True], hits[1:, 0] != hits[:-1, 0]))
        found[hits[first, 0]] = hits[first, 1]
        depth[hits[first, 0]] = hit_depth[first]
    return found, depth


@njit(cache=True, parallel=True)
def _pair_depths(
    points: np.ndarray, vertices: np.ndarray, cells: np.ndarray, pairs: np.ndarray
) -> np.ndarray:
    """Smallest barycentric coordinate ``(n,)`` of point ``pairs[i, 0]`` in cell ``pairs[i, 1]``."""
    n, d = pairs.shape[0], points.shape[1]
    out = np.empty(n)
    for i in prange(n):
        v = np.empty((d + 1, d))
        for a in range(d + 1):
            v[a] = vertices[cells[pairs[i, 1], a]]
        out[i] = simplex_depth(points[pairs[i, 0]], v)
    return out


def _points(model: Model, state: State) -> tuple[np.ndarray, np.ndarray]:
    """Test points ``(N + P + M, d)``: FEM nodes, particles, then FEM cell centroids (which see
    bodies that overlap with every vertex on the other's surface, e.g. equal aligned boxes), and
    their body ids (particles < 0)."""
    body = np.repeat(
        np.array([b.index for b in model.fem_bodies], dtype=np.int64),
        [b.n_nodes for b in model.fem_bodies],
    )
    centroids = state.fem_x[model.fem_cells].mean(axis=1)
    return (
        np.concatenate([state.fem_x, state.mpm_x, centroids]),
        np.concatenate([body, -1 - model.mpm_particle_body, model.fem_cell_body]),
    )


def _describe(model: Model, point: int, cell: int, status: str, s: float, n: int) -> Intersection:
    n_fem, n_mpm = model.n_fem_nodes, model.n_particles
    if point < n_fem:
        what = _node_name(model, point)[0]
    elif point < n_fem + n_mpm:
        p = point - n_fem
        owner = model.mpm_bodies[int(model.mpm_particle_body[p])]
        what = f"particle {p - owner.particles.start} of body {owner.name!r}"
    else:
        c = point - n_fem - n_mpm
        owner = model.fem_bodies[int(model.fem_cell_body[c])]
        what = f"the centroid of cell {c - owner.cells.start} of body {owner.name!r}"
    body = model.fem_bodies[int(model.fem_cell_body[cell])].name
    return Intersection(status=status, s=s, n_points=n, point=what, body=body)


def _node_name(model: Model, node: int) -> tuple[str, str]:
    """``("FEM node i of body 'A'", "A")`` for a global FEM node index."""
    owner = next(b for b in model.fem_bodies if b.nodes.start <= node < b.nodes.stop)
    return f"FEM node {node - owner.nodes.start} of body {owner.name!r}", owner.name


def _point_name(model: Model, cs: CollisionSet, c: int) -> str:
    """Name of collision point c (FEM boundary node or particle)."""
    if c < cs.n_fem_points:
        return _node_name(model, int(cs.nodes[c, 0]))[0]
    p = int(cs.particle_index[c])
    owner = model.mpm_bodies[int(model.mpm_particle_body[p])]
    return f"particle {p - owner.particles.start} of body {owner.name!r}"


#: id(model) -> (weak reference to the model, its collision set): built once per model
_POINTS_CACHE: dict[int, tuple[weakref.ref, CollisionSet]] = {}


def end_of_step_points(model: Model) -> CollisionSet:
    """The collision points and facets of the end-of-step check: every FEM boundary node and
    every particle (as itself: all-node positions are ``[fem_x; mpm_x]``, particle p is node
    ``N + p``), the FEM boundary facets and (3D) boundary edges, with their bodies
    (``bfemp.contact.collision``). Built once per model (10-30 ms for 58k tetrahedra)."""
    cached = _POINTS_CACHE.get(id(model))
    if cached is not None and cached[0]() is model:
        return cached[1]
    n_fem, n_mpm = model.n_fem_nodes, model.n_particles
    particles = None
    if n_mpm:  # particle p is all-node N + p, weight 1
        nodes = (n_fem + np.arange(n_mpm, dtype=np.int64))[:, None]
        particles = PointStencils(nodes, np.ones((n_mpm, 1)))
    cs = build_collision_set(model, particles)
    for key in [k for k, (ref, _) in _POINTS_CACHE.items() if ref() is None]:
        del _POINTS_CACHE[key]
    _POINTS_CACHE[id(model)] = (weakref.ref(model), cs)
    return cs
