"""Independent check that no FEM node or MPM particle lies inside another FEM body, at the end
of a step and along its straight-line motion.

The barrier and its CCD-filtered line search guarantee that the Newton iterates, and the straight
segments between them, never cross a boundary (section 5). They do not make the step's own
straight-line trajectory x^n -> x^{n+1} (what the frames and the velocity v^{n+1} describe) free
of crossings: with a step far larger than the bodies (|v| dt >> size), frictionless iterates can
slide one body *around* the other in configuration space to the free-flight prediction x-hat, so
every iterate is clear, the end state is clear, and yet the bodies have passed through each other
within the step. This module checks both, with geometry of its own (no barrier, no CCD):

- the end state: every FEM node (interior ones too), every particle and every FEM cell centroid
  (which sees bodies overlapping with all vertices on the other's surface, e.g. equal aligned
  boxes) is tested against the cells (triangles / tetrahedra) of every *other* FEM body. Any
  point strictly inside is an ``"INTERSECTION"``.
- the trajectory: the same test at interior samples s_k = k / K of the linear-in-time motion,
  K set so that no two points move more than ``spacing`` (a quarter of the smallest mean rest
  boundary-edge length over the FEM bodies) relative to each other between samples. A point
  counts only if it lies deeper than ``depth`` (the contact's d-hat) inside the other body,
  farther than that from its boundary, and, if it touches that body (within ``depth``) at the
  start or the end of the step, deeper than a corner-cut allowance: a point sliding past (or
  flying off) a convex boundary vertex of turn angle theta legitimately cuts the corner on its
  chord by (L / 2) tan(theta / 2), L its relative move; the allowance is L / 2, capped at a
  quarter of that body's mean boundary edge (measured on the sine-boundary benchmark's quick
  mode, 90-degree vertices: cuts of 1.7-1.8 mm against d-hat = 1 mm). Any counted point is
  ``"TUNNELED"``. A pass through a region thicker than ``spacing`` + 2 ``depth`` (+ 2 x the cap
  when starting or ending in contact) is always found.

Broad phase: the spatial hash of :mod:`geometry.broadphase` (swept boxes for the trajectory);
narrow phase: numba kernels over the candidate (point, cell) pairs; along the trajectory the
swept candidates are rebuilt per chunk of 32 samples, so bodies that only pass near each other
cost little. Measured on the rings demo (``bfemp.demo.colliding_rings_scene()``, dt = 2e-3 s,
381 FEM nodes, 784 particles, 610 cells, steps 3-60): 1.4-3.0 ms per step, 1.9-2.5 % of the
step time in four runs (a step there moves points about one ``spacing``: two or three samples). At
dt = 1e-2 s the demo's 30 steps to t = 0.3 s all pass the check.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from bfemp.model import Model
from bfemp.state import State
from geometry._distance_kernels import KIND_PE, KIND_PT, _classify
from geometry.broadphase import point_simplex_candidates

__all__ = [
    "Intersection",
    "MAX_SAMPLES",
    "body_spacing",
    "sample_spacing",
    "points_inside",
    "step_intersection",
]

log = logging.getLogger(__name__)

#: Cap on the interior samples of a step's trajectory (beyond it the sampling step in relative
#: motion exceeds ``spacing``; a warning is logged).
MAX_SAMPLES = 4096

#: Samples per swept broad phase along a step's trajectory.
_CHUNK = 32

#: Strict inside test: every barycentric coordinate above this (dimensionless).
_BARY_EPS = 1e-12


@dataclass(frozen=True)
class Intersection:
    """The first crossing found in a step.

    Attributes:
        status: ``"INTERSECTION"`` (at the end of the step) or ``"TUNNELED"`` (inside the step's
            straight-line trajectory only).
        s: fraction of the step at which it was found (1.0 for the end state).
        n_points: number of points found inside another body at that sample.
        point: ``"FEM node i of body 'A'"``, ``"particle i of body 'B'"`` or ``"the centroid of
            cell i of body 'A'"`` (indices local to the body).
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
        where = "at the end of the step" if self.s >= 1.0 else f"at {self.s:.3g} of the step"
        text = (
            f"{self.n_points} point(s) inside another FEM body {where}, e.g. {self.point} "
            f"inside body {self.body!r}"
        )
        if self.status == "TUNNELED":
            text += (
                " (the end state is clear, but the step's straight-line motion passes through: "
                "the time step is too large for this collision; reduce dt)"
            )
        return text


# ---------------------------------------------------------------------------- kernels


@njit(cache=True)
def _barycentric_min(y: np.ndarray, v: np.ndarray) -> float:
    """Smallest barycentric coordinate of point y (d,) in the simplex v (d + 1, d)."""
    d = y.shape[0]
    if d == 2:
        a0, a1 = v[1, 0] - v[0, 0], v[1, 1] - v[0, 1]
        b0, b1 = v[2, 0] - v[0, 0], v[2, 1] - v[0, 1]
        r0, r1 = y[0] - v[0, 0], y[1] - v[0, 1]
        det = a0 * b1 - a1 * b0
        if det == 0.0:
            return -1.0
        l1 = (r0 * b1 - r1 * b0) / det
        l2 = (a0 * r1 - a1 * r0) / det
        return min(1.0 - l1 - l2, l1, l2)
    m = np.empty((3, 3))
    for c in range(3):
        for k in range(3):
            m[k, c] = v[c + 1, k] - v[0, k]
    r = y - v[0]
    det = (
        m[0, 0] * (m[1, 1] * m[2, 2] - m[1, 2] * m[2, 1])
        - m[0, 1] * (m[1, 0] * m[2, 2] - m[1, 2] * m[2, 0])
        + m[0, 2] * (m[1, 0] * m[2, 1] - m[1, 1] * m[2, 0])
    )
    if det == 0.0:
        return -1.0
    lam_min = 1.0
    total = 0.0
    for c in range(3):  # Cramer's rule: column c replaced by r
        mc = m.copy()
        for k in range(3):
            mc[k, c] = r[k]
        dc = (
            mc[0, 0] * (mc[1, 1] * mc[2, 2] - mc[1, 2] * mc[2, 1])
            - mc[0, 1] * (mc[1, 0] * mc[2, 2] - mc[1, 2] * mc[2, 0])
            + mc[0, 2] * (mc[1, 0] * mc[2, 1] - mc[1, 1] * mc[2, 0])
        )
        lam = dc / det
        total += lam
        lam_min = min(lam_min, lam)
    return min(lam_min, 1.0 - total)


@njit(cache=True, parallel=True)
def _inside_pairs(
    y0: np.ndarray,
    y1: np.ndarray,
    v0: np.ndarray,
    v1: np.ndarray,
    cells: np.ndarray,
    pairs: np.ndarray,
    s: float,
) -> np.ndarray:
    """Whether point ``pairs[i, 0]`` lies strictly inside cell ``pairs[i, 1]`` at time s.

    Points move y0 -> y1 ``(P, d)``, cell vertices v0 -> v1 ``(V, d)`` (positions (1-s) a + s b).
    """
    n = pairs.shape[0]
    d = y0.shape[1]
    out = np.zeros(n, dtype=np.bool_)
    for i in prange(n):
        q, c = pairs[i, 0], pairs[i, 1]
        y = (1.0 - s) * y0[q] + s * y1[q]
        v = np.empty((d + 1, d))
        for a in range(d + 1):
            v[a] = (1.0 - s) * v0[cells[c, a]] + s * v1[cells[c, a]]
        out[i] = _barycentric_min(y, v) > _BARY_EPS
    return out


@njit(cache=True, parallel=True)
def _surface_distance(
    y0: np.ndarray,
    y1: np.ndarray,
    v0: np.ndarray,
    v1: np.ndarray,
    facets: np.ndarray,
    facet_start: np.ndarray,
    point: np.ndarray,
    body: np.ndarray,
    s: float,
) -> np.ndarray:
    """Distance ``(n,)`` in m at time s of point ``point[i]`` to the boundary facets of body
    ``body[i]`` (``facets[facet_start[b]:facet_start[b + 1]]``), by brute force over them."""
    n = point.shape[0]
    d = y0.shape[1]
    kind = KIND_PE if d == 2 else KIND_PT
    out = np.empty(n)
    for i in prange(n):
        X = np.empty((d + 1, d))
        X[0] = (1.0 - s) * y0[point[i]] + s * y1[point[i]]
        best = np.inf
        for f in range(facet_start[body[i]], facet_start[body[i] + 1]):
            for a in range(d):
                X[a + 1] = (1.0 - s) * v0[facets[f, a]] + s * v1[facets[f, a]]
            best = min(best, _classify(X, kind)[1])
        out[i] = np.sqrt(best)
    return out


# ---------------------------------------------------------------------------- drivers


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
    hits = _hits(points, points, point_body, vertices, vertices, cells, cell_body, 1.0)
    out = np.full(points.shape[0], -1, dtype=np.int64)
    if hits.shape[0]:
        first = np.concatenate(([True], hits[1:, 0] != hits[:-1, 0]))
        out[hits[first, 0]] = hits[first, 1]
    return out


def _candidates(
    y0: np.ndarray,
    y1: np.ndarray,
    point_body: np.ndarray,
    v0: np.ndarray,
    v1: np.ndarray,
    simplices: np.ndarray,
    simplex_body: np.ndarray,
    inflation: float = 0.0,
) -> np.ndarray:
    """(point, simplex) pairs of different bodies whose boxes swept y0 -> y1 / v0 -> v1 overlap."""
    swept = y1 is not y0
    cand = point_simplex_candidates(
        y0,
        v0,
        simplices,
        inflation=inflation,
        points_end=y1 if swept else None,
        vertices_end=v1 if swept else None,
    )
    return cand[point_body[cand[:, 0]] != simplex_body[cand[:, 1]]]


def _hits(
    y0: np.ndarray,
    y1: np.ndarray,
    point_body: np.ndarray,
    v0: np.ndarray,
    v1: np.ndarray,
    cells: np.ndarray,
    cell_body: np.ndarray,
    s: float,
    cand: np.ndarray | None = None,
) -> np.ndarray:
    """Candidate (point, cell) rows ``(n, 2)`` with the point strictly inside at time s.

    Points move y0 -> y1 ``(P, d)``, cell vertices v0 -> v1 ``(V, d)``; ``cand`` (pairs of
    different bodies whose boxes contain the time-s positions) defaults to a static broad phase
    at time s.
    """
    if cand is None:
        ys, vs = (1.0 - s) * y0 + s * y1, (1.0 - s) * v0 + s * v1
        cand = _candidates(ys, ys, point_body, vs, vs, cells, cell_body)
    if cand.shape[0] == 0:
        return cand
    return cand[_inside_pairs(y0, y1, v0, v1, cells, cand, s)]


def body_spacing(model: Model) -> np.ndarray:
    """A quarter of each FEM body's mean rest boundary-edge length ``(n_fem_bodies,)`` in m (by
    body index)."""
    out = np.zeros(len(model.fem_bodies))
    for body in model.fem_bodies:
        b = body.boundary  # 2D: the facets are the edges; 3D: the triangles' three edges
        edges = b if b.shape[1] == 2 else np.concatenate([b[:, [0, 1]], b[:, [1, 2]], b[:, [2, 0]]])
        length = np.linalg.norm(model.fem_X[edges[:, 1]] - model.fem_X[edges[:, 0]], axis=1)
        out[body.index] = 0.25 * length.mean()
    return out


def sample_spacing(model: Model) -> float:
    """The smallest :func:`body_spacing`, in m: the trajectory's sampling step."""
    return float(body_spacing(model).min())


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
        owner = next(b for b in model.fem_bodies if b.nodes.start <= point < b.nodes.stop)
        what = f"FEM node {point - owner.nodes.start} of body {owner.name!r}"
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


def step_intersection(
    model: Model,
    start: State,
    end: State,
    *,
    depth: float | None = None,
    spacing: float | None = None,
) -> Intersection | None:
    """The first crossing of the step ``start -> end``, or None when there is none.

    Tests the end state (any point strictly inside another body) and, when points move more than
    ``spacing`` relative to each other, the straight-line trajectory at interior samples (a point
    deeper than ``depth`` inside another body); see the module docstring.

    Args:
        model: the static model (FEM cells, bodies, particles, contact).
        start, end: states at the start and the end of the step.
        depth: the trajectory's depth tolerance in m (default: the contact's d-hat, else
            :func:`sample_spacing`).
        spacing: the largest relative motion between samples in m (default
            :func:`sample_spacing`).
    """
    if len(model.fem_bodies) == 0:
        return None
    cells, cell_body = model.fem_cells, model.fem_cell_body
    y0, body = _points(model, start)
    y1, _ = _points(model, end)
    v0, v1 = start.fem_x, end.fem_x
    hits = _hits(y1, y1, body, v1, v1, cells, cell_body, 1.0)
    if hits.shape[0]:
        n = np.unique(hits[:, 0]).size
        return _describe(model, int(hits[0, 0]), int(hits[0, 1]), "INTERSECTION", 1.0, n)
    spacing = sample_spacing(model) if spacing is None else float(spacing)
    if depth is None:
        depth = model.contact.dhat if model.contact is not None else spacing
    # relative motion of any two points between samples <= 2 max |y1 - y0| / K <= spacing
    motion = 2.0 * float(np.linalg.norm(y1 - y0, axis=1).max(initial=0.0))
    n_samples = int(np.ceil(motion / spacing))
    if n_samples <= 1:
        return None
    if n_samples > _CHUNK and _candidates(y0, y1, body, v0, v1, cells, cell_body).size == 0:
        return None  # nothing comes near another body on the whole step
    if n_samples > MAX_SAMPLES:
        log.warning(
            "step trajectory sampled %d times, coarser than the spacing %.3g m (needs %d)",
            MAX_SAMPLES,
            spacing,
            n_samples,
        )
        n_samples = MAX_SAMPLES
    facets, facet_start = _boundary_facets(model)
    motion = (y0, y1, v0, v1)
    for first in range(1, n_samples, _CHUNK):  # in order: the first deep point is reported
        ks = np.arange(first, min(first + _CHUNK, n_samples))
        # candidates swept over the chunk's part of the step only (positions are linear in s)
        sa, sb = ks[0] / n_samples, ks[-1] / n_samples
        ya, yb = (1.0 - sa) * y0 + sa * y1, (1.0 - sb) * y0 + sb * y1
        va, vb = (1.0 - sa) * v0 + sa * v1, (1.0 - sb) * v0 + sb * v1
        cand = _candidates(ya, yb, body, va, vb, cells, cell_body)
        if cand.shape[0] == 0:
            continue
        for k in ks:
            s = k / n_samples
            inside = _hits(y0, y1, body, v0, v1, cells, cell_body, s, cand)
            if inside.shape[0] == 0:
                continue
            deep = _deep(inside, motion, model, facets, facet_start, s, depth)
            if deep.shape[0]:
                n = np.unique(deep[:, 0]).size
                return _describe(model, int(deep[0, 0]), int(deep[0, 1]), "TUNNELED", s, n)
    return None


def _boundary_facets(model: Model) -> tuple[np.ndarray, np.ndarray]:
    """All FEM boundary facets ``(F, d)`` (global node indices), body by body, and each body's
    first facet ``(n_bodies + 1,)`` (body b owns ``facets[start[b]:start[b + 1]]``)."""
    bodies = sorted(model.fem_bodies, key=lambda b: b.index)
    facets = np.concatenate([b.boundary for b in bodies])
    start = np.concatenate([[0], np.cumsum([b.boundary.shape[0] for b in bodies])])
    return np.ascontiguousarray(facets, dtype=np.int64), start.astype(np.int64)


def _deep(
    inside: np.ndarray,
    motion: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    model: Model,
    facets: np.ndarray,
    facet_start: np.ndarray,
    s: float,
    depth: float,
) -> np.ndarray:
    """The (point, cell) rows of ``inside`` (at time s) that count as a crossing.

    A point counts when it lies deeper inside the cell's body than ``depth`` and than its
    corner-cut allowance. A point within ``depth`` of that body's surface at the start or the end
    of the step (sliding contact, or leaving it) may cut a convex corner of turn angle theta on
    its chord by (L / 2) tan(theta / 2), L its motion relative to the cell over the step: the
    allowance is L / 2 (corners up to 90 degrees), capped at the body's :func:`body_spacing` (a
    quarter edge: a corner cut stays near the corner, a pass-through goes deeper). Points away
    from the body at both ends get no allowance. ``motion``: y0, y1, v0, v1 as in :func:`_hits`.
    """
    y0, y1, v0, v1 = motion
    point = np.ascontiguousarray(inside[:, 0])
    cell = inside[:, 1]
    body = np.ascontiguousarray(model.fem_cell_body[cell])
    args = (y0, y1, v0, v1, facets, facet_start, point, body)
    d_s = _surface_distance(*args, s)
    touching = (_surface_distance(*args, 0.0) <= depth) | (_surface_distance(*args, 1.0) <= depth)
    nodes = model.fem_cells[cell]
    relative = (y1[point] - y0[point]) - (v1[nodes] - v0[nodes]).mean(axis=1)
    cut = np.minimum(0.5 * np.linalg.norm(relative, axis=1), body_spacing(model)[body])
    allowance = np.where(touching, cut, 0.0)
    return inside[d_s > np.maximum(depth, allowance)]
