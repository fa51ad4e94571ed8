"""Vectorised building blocks of the shape generators in :mod:`geometry.shapes`.

- :func:`strip_triangles` triangulates the band between two polylines (rings of nodes);
- :func:`ring_stack` builds concentric circles or arcs of nodes and triangulates between them;
- :func:`grid_triangles` / :func:`grid_triangles_crossed` split a structured quad grid;
- :func:`split_hexes` splits any hexahedral mesh into tetrahedra conformingly.

Band triangulation: the band between an inner polyline ``p_0..p_a`` and an outer one
``q_0..q_b`` is covered by ``a + b`` triangles, each advancing one of the two polylines by one
node. Advancing the inner polyline from the diagonal ``(p_i, q_j)`` adds ``(p_i, q_j, p_{i+1})``,
advancing the outer one adds ``(q_j, q_{j+1}, p_i)``. Choosing the shorter of the two candidate
diagonals (``p_{i+1} q_j`` vs ``p_i q_{j+1}``) at every step is, on concentric circles where the
chord length only depends on the angle difference, the same as merging the two polylines' edges
by their mid-angles. That merge is one ``argsort``, so the whole band is vectorised.

Hexahedron split (conforming for any hex mesh): in each hex let ``v0`` be the vertex with the
smallest global index. Every quad face not containing ``v0`` is cut by its diagonal through that
face's smallest-index vertex, and each of its two triangles is joined to ``v0`` (6 tetrahedra).
A face containing ``v0`` is thereby fanned from ``v0``, which is also its smallest vertex. So a
face shared by two hexes is always cut along the diagonal through its smallest-index vertex, by
both neighbours alike: the tetrahedral mesh is conforming.
"""

from __future__ import annotations

import numpy as np

from geometry._meshing_metrics import oriented_cells, signed_measures

#: (i, j, k) offsets of a hexahedron's 8 corners in VTK vertex order (:func:`split_hexes`)
HEX_CORNERS = tuple(tuple(map(int, c)) for c in "000 100 110 010 001 101 111 011".split())

# Quad faces of a hexahedron in VTK order (0:000, 1:100, 2:110, 3:010, 4:001, 5:101, 6:111,
# 7:011), each listed as a cycle around the face.
HEX_FACES = np.array(
    [[0, 1, 2, 3], [4, 5, 6, 7], [0, 1, 5, 4], [3, 2, 6, 7], [0, 3, 7, 4], [1, 2, 6, 5]],
    dtype=np.int64,
)
# For each local vertex: the three faces that do not contain it, shape (8, 3, 4).
_FAR_FACES = np.array(
    [HEX_FACES[[f for f in range(6) if v not in HEX_FACES[f]]] for v in range(8)],
    dtype=np.int64,
)


def strip_triangles(
    inner: np.ndarray, inner_t: np.ndarray, outer: np.ndarray, outer_t: np.ndarray, closed: bool
) -> np.ndarray:
    """Triangulate the band between two polylines of node indices.

    Args:
        inner: (a,) node indices of the inner polyline, counter-clockwise.
        inner_t: (a,) increasing curve parameters (fraction of the full turn or arc) of ``inner``.
        outer: (b,) node indices of the outer polyline, same sense.
        outer_t: (b,) increasing parameters of ``outer``.
        closed: closed loops (parameters in [0, 1), wrap-around edge added) or open arcs
            (both polylines start together at parameter 0 and end together at 1).

    Returns:
        (a + b, 3) counter-clockwise triangles (closed) or (a + b - 2, 3) (open).
    """
    a, b = inner.size, outer.size
    if closed:
        ti = np.append(inner_t, inner_t[0] + 1.0)
        to = np.append(outer_t, outer_t[0] + 1.0)
        pi, po = np.append(inner, inner[0]), np.append(outer, outer[0])
    else:
        ti, to, pi, po = inner_t, outer_t, inner, outer
    key = np.concatenate([0.5 * (ti[1:] + ti[:-1]), 0.5 * (to[1:] + to[:-1])])
    is_inner = np.concatenate([np.ones(ti.size - 1, bool), np.zeros(to.size - 1, bool)])
    order = np.argsort(key, kind="stable")
    is_inner = is_inner[order]
    i = np.cumsum(is_inner) - is_inner
    j = np.cumsum(~is_inner) - ~is_inner
    tri = np.where(
        is_inner[:, None],
        np.stack([pi[i], po[j], pi[np.minimum(i + 1, a if closed else a - 1)]], axis=1),
        np.stack([po[j], po[np.minimum(j + 1, b if closed else b - 1)], pi[i]], axis=1),
    )
    return tri.astype(np.int64)


def ring_stack(
    center: np.ndarray, radii: np.ndarray, counts: np.ndarray, arc: float
) -> tuple[np.ndarray, np.ndarray]:
    """Concentric rings (``arc = 2 pi``) or arcs from angle 0 to ``arc`` triangulated in bands.

    Args:
        center: (2,) centre, metres.
        radii: (L,) increasing ring radii, metres; ``radii[0] == 0`` puts one node at the centre
            (full circles only) that is fanned to ring 1.
        counts: (L,) number of segments per ring (closed rings have as many nodes).
        arc: 2 pi for closed rings, otherwise the opening angle (rad) of open arcs.

    Returns:
        ``(points (n, 2), cells (m, 3))`` with counter-clockwise cells.
    """
    closed = bool(np.isclose(arc, 2.0 * np.pi))
    params, starts = [], [0]
    for r, n in zip(radii, counts, strict=True):
        if r == 0.0:
            t = np.zeros(1)
        elif closed:
            t = np.arange(n) / n
        else:
            t = np.arange(n + 1) / n
        params.append(t)
        starts.append(starts[-1] + t.size)
    theta = arc * np.concatenate(params)
    rad = np.repeat(radii, [t.size for t in params])
    points = center + rad[:, None] * np.stack([np.cos(theta), np.sin(theta)], axis=1)
    cells = []
    for k in range(len(radii) - 1):
        inner = np.arange(starts[k], starts[k + 1])
        outer = np.arange(starts[k + 1], starts[k + 2])
        if inner.size == 1:
            cells.append(np.stack([np.full(outer.size, inner[0]), outer, np.roll(outer, -1)], 1))
        else:
            cells.append(strip_triangles(inner, params[k], outer, params[k + 1], closed))
    return np.ascontiguousarray(points), np.ascontiguousarray(np.concatenate(cells))


def grid_triangles(nx: int, ny: int, main_diagonal: np.ndarray) -> np.ndarray:
    """Triangles of an ``nx`` by ``ny`` quad grid of nodes ``j * (nx + 1) + i``, shape (2 nx ny, 3).

    Quad ``q = j * nx + i`` is cut along ``n00-n11`` where ``main_diagonal[q]`` (shape (nx ny,))
    is true, else along ``n10-n01``. Counter-clockwise when x grows with i and y with j.
    """
    n00, n10, n01, n11 = _quad_corners(nx, ny)
    main = np.asarray(main_diagonal, dtype=bool)[:, None]
    first = np.where(main, np.stack([n00, n10, n11], 1), np.stack([n00, n10, n01], 1))
    second = np.where(main, np.stack([n00, n11, n01], 1), np.stack([n10, n11, n01], 1))
    return np.stack([first, second], axis=1).reshape(-1, 3)


def checkerboard(nx: int, ny: int) -> np.ndarray:
    """(nx ny,) flags alternating like a checkerboard: the 'union jack' diagonal pattern."""
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="xy")
    return ((i + j) % 2 == 0).ravel()


def shorter_diagonal(points: np.ndarray, nx: int, ny: int) -> np.ndarray:
    """(nx ny,) flags: true where ``n00-n11`` is not longer than ``n10-n01`` (Delaunay for
    parallelograms: the cut joins the obtuse corners)."""
    n00, n10, n01, n11 = _quad_corners(nx, ny)
    d_main = np.sum((points[n11] - points[n00]) ** 2, axis=1)
    d_anti = np.sum((points[n01] - points[n10]) ** 2, axis=1)
    return d_main <= d_anti


def grid_triangles_crossed(nx: int, ny: int) -> np.ndarray:
    """Triangles (4 nx ny, 3) cutting each quad by both diagonals through a centre node.

    The centre of quad ``j * nx + i`` is node ``(nx + 1)(ny + 1) + j nx + i``.
    """
    n00, n10, n01, n11 = _quad_corners(nx, ny)
    c = (nx + 1) * (ny + 1) + np.arange(nx * ny)
    tri = [np.stack(e, 1) for e in ((n00, n10, c), (n10, n11, c), (n11, n01, c), (n01, n00, c))]
    return np.stack(tri, axis=1).reshape(-1, 3)


def _quad_corners(nx: int, ny: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Node indices (n00, n10, n01, n11) of each quad of the structured grid, each (nx ny,)."""
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="xy")
    n00 = (j * (nx + 1) + i).ravel()
    return n00, n00 + 1, n00 + nx + 1, n00 + nx + 2


def split_hexes(points: np.ndarray, hexes: np.ndarray) -> np.ndarray:
    """Split hexahedra (k, 8) in VTK vertex order into 6 k right-handed tetrahedra (6 k, 4).

    Conforming across shared faces for any hex mesh (rule in the module docstring).
    ``points`` (n, 3) in metres is used only to orient the tetrahedra.
    """
    local_v0 = np.argmin(hexes, axis=1)  # (k,)
    v0 = hexes[np.arange(hexes.shape[0]), local_v0]
    rows = np.arange(hexes.shape[0])[:, None, None]
    far = hexes[rows, _FAR_FACES[local_v0]]  # (k, 3, 4) global vertex cycles of the far faces
    start = np.argmin(far, axis=2)  # smallest vertex of each face starts the cycle
    cyc = (start[..., None] + np.arange(4)) % 4
    face = np.take_along_axis(far, cyc, axis=2)
    tri = np.stack([face[..., [0, 1, 2]], face[..., [0, 2, 3]]], axis=2)  # (k, 3, 2, 3)
    tets = np.concatenate(
        [np.broadcast_to(v0[:, None, None, None], (*tri.shape[:3], 1)), tri], axis=3
    ).reshape(-1, 4)
    return np.ascontiguousarray(oriented_cells(tets, signed_measures(points, tets)))
