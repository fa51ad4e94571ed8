"""Vectorised simplex-mesh metrics and topology used by :mod:`geometry.mesh`.

Private helpers on plain arrays (no mesh objects), so that they can be tested and reused:

- signed cell measures (area in 2D, volume in 3D) in m^2 / m^3,
- normalised radius-ratio quality ``d * r_in / r_circ`` in ``[0, 1]`` (1 = equilateral),
- corner angles of triangles,
- facet (edge / face) extraction with outward orientation and boundary detection.

Orientation conventions: a triangle ``(a, b, c)`` is positive when counter-clockwise,
``det[b - a, c - a] > 0``; a tetrahedron ``(a, b, c, d)`` is positive when right-handed,
``det[b - a, c - a, d - a] > 0``. For a positive cell the local facets below are ordered so that
their normals (2D: ``(dy, -dx)`` of the directed edge; 3D: right-hand rule) point out of the cell.
"""

from __future__ import annotations

import numpy as np

# Local facets of a positive cell with outward orientation.
# Triangle: the body is on the left of each directed edge a->b.
TRI_FACETS = np.array([[0, 1], [1, 2], [2, 0]], dtype=np.int64)
# Tetrahedron: facet i is opposite vertex i, ordered so the right-hand normal points away from i.
TET_FACETS = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]], dtype=np.int64)
# All edges of a tetrahedron.
TET_EDGES = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]], dtype=np.int64)


def cell_edge_vectors(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Edge vectors ``x_i - x_0`` (i = 1..d) of every cell, shape (m, d, d), metres."""
    x0 = points[cells[:, 0]]
    return points[cells[:, 1:]] - x0[:, None, :]


def signed_measures(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Signed area (2D, m^2) or volume (3D, m^3) of each simplex, shape (m,).

    ``det[x_1 - x_0, ..., x_d - x_0] / d!`` with the edge vectors as columns.
    """
    e = cell_edge_vectors(points, cells)
    if points.shape[1] == 2:
        return 0.5 * (e[:, 0, 0] * e[:, 1, 1] - e[:, 0, 1] * e[:, 1, 0])
    return np.einsum("ij,ij->i", e[:, 0], np.cross(e[:, 1], e[:, 2])) / 6.0


def edge_lengths(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Lengths of the edges of every cell, shape (m, 3) in 2D or (m, 6) in 3D, metres."""
    local = TRI_FACETS if cells.shape[1] == 3 else TET_EDGES
    d = points[cells[:, local[:, 1]]] - points[cells[:, local[:, 0]]]
    return np.sqrt(np.einsum("mek,mek->me", d, d))


def radius_ratio(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Normalised radius ratio ``d r_in / r_circ`` of each simplex in [0, 1], shape (m,).

    2D: ``2 r / R = 16 A^2 / ((a + b + c) a b c)``. 3D: ``r = 3 V / S`` (S = total face area) and
    ``R = |a^2 (b x c) + b^2 (c x a) + c^2 (a x b)| / (12 V)`` with a, b, c the edge vectors from
    vertex 0, so ``3 r / R = 108 V^2 / (S |N|)``. Both equal 1 for the equilateral simplex and
    tend to 0 for slivers, needles and caps. Orientation is ignored (|V| is used).
    """
    vol = signed_measures(points, cells)
    if points.shape[1] == 2:
        lengths = edge_lengths(points, cells)
        num = 16.0 * vol**2
        den = lengths.sum(axis=1) * lengths.prod(axis=1)
    else:
        e = cell_edge_vectors(points, cells)
        a, b, c = e[:, 0], e[:, 1], e[:, 2]
        sq = np.einsum("mij,mij->mi", e, e)
        circ = (
            sq[:, 0, None] * np.cross(b, c)
            + sq[:, 1, None] * np.cross(c, a)
            + sq[:, 2, None] * np.cross(a, b)
        )
        fx = points[cells[:, TET_FACETS]]  # (m, 4, 3, 3)
        fn = np.cross(fx[:, :, 1] - fx[:, :, 0], fx[:, :, 2] - fx[:, :, 0])
        area = 0.5 * np.sqrt(np.einsum("mfk,mfk->mf", fn, fn)).sum(axis=1)
        num = 108.0 * vol**2
        den = area * np.sqrt(np.einsum("mk,mk->m", circ, circ))
    out = np.zeros_like(vol)
    np.divide(num, den, out=out, where=den > 0.0)
    return np.clip(out, 0.0, 1.0)


def triangle_angles(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Interior angle at each corner of each triangle, shape (m, 3), radians.

    Angle at corner i between the edges to the two other corners: ``atan2(|u x v|, u . v)``.
    """
    x = points[cells]  # (m, 3, 2)
    u = np.roll(x, -1, axis=1) - x
    v = np.roll(x, 1, axis=1) - x
    cross = np.abs(u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0])
    dot = np.einsum("mck,mck->mc", u, v)
    return np.arctan2(cross, dot)


def unique_rows(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unique rows of an integer array via lexicographic sort.

    Returns ``(unique (u, c), inverse (k,), counts (u,))`` with ``unique[inverse] == rows``.
    """
    k = rows.shape[0]
    if k == 0:
        empty = np.empty((0, rows.shape[1]), dtype=rows.dtype)
        return empty, np.empty(0, dtype=np.int64), np.empty(0, dtype=np.int64)
    order = np.lexsort(rows.T[::-1])
    srt = rows[order]
    new = np.empty(k, dtype=bool)
    new[0] = True
    np.any(srt[1:] != srt[:-1], axis=1, out=new[1:])
    group = np.cumsum(new) - 1
    inverse = np.empty(k, dtype=np.int64)
    inverse[order] = group
    counts = np.bincount(group)
    return srt[new], inverse, counts


def oriented_cells(cells: np.ndarray, measures: np.ndarray) -> np.ndarray:
    """Copy of ``cells`` (m, d+1) with the last two vertices swapped where ``measures < 0``."""
    out = cells.copy()
    neg = measures < 0.0
    out[neg, -2], out[neg, -1] = cells[neg, -1], cells[neg, -2]
    return out


def facets(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Outward-oriented facets of every cell and their sharing counts.

    Returns ``(directed (m * (d+1), d), inverse (m * (d+1),), counts (u,))``: the facets in the
    cells' own orientation (facet ``d+1 * c + i`` is opposite local vertex i of cell c for
    tetrahedra), the index of each facet's sorted key among the unique facets, and how many cells
    share each unique facet (1 = boundary, 2 = interior, >2 = non-manifold).
    """
    local = TRI_FACETS if cells.shape[1] == 3 else TET_FACETS
    directed = cells[:, local].reshape(-1, cells.shape[1] - 1)
    _, inverse, counts = unique_rows(np.sort(directed, axis=1))
    return directed, inverse, counts


def boundary_facets(cells: np.ndarray) -> np.ndarray:
    """Facets used by exactly one cell, in the cell's outward orientation, shape (k, d).

    ``cells`` must be positively oriented for the result to be outward.
    """
    directed, inverse, counts = facets(cells)
    return np.ascontiguousarray(directed[counts[inverse] == 1])


def facet_normals(points: np.ndarray, facet_vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit normals (k, d) and measures (k,) of directed facets (k, d) (edges 2D, triangles 3D).

    2D: normal ``(dy, -dx) / L`` of the directed edge a->b, measure L (m).
    3D: normal ``(b - a) x (c - a) / (2 A)``, measure A (m^2).
    """
    x = points[facet_vertices]
    if points.shape[1] == 2:
        d = x[:, 1] - x[:, 0]
        n = np.stack([d[:, 1], -d[:, 0]], axis=1)
    else:
        n = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    length = np.sqrt(np.einsum("ij,ij->i", n, n))
    unit = np.zeros_like(n)
    np.divide(n, length[:, None], out=unit, where=length[:, None] > 0.0)
    measure = length if points.shape[1] == 2 else 0.5 * length
    return unit, measure
