"""Closest-point parameters and tangent bases of contact primitive pairs (for lagged friction).

Batched over ``n`` pairs, arguments ``(n, d)`` in m as in :mod:`geometry.distance` (point-point
and point-edge in 2D and 3D, point-triangle and edge-edge in 3D).

Closest-point parameters follow the closest-feature type of :mod:`geometry.distance` (same
classification kernel), so they are consistent with the distance and its derivatives:

- point-edge: ``beta`` with closest point ``(1 - beta) e0 + beta e1`` (the clamped projection;
  0 for a zero-length edge);
- point-triangle: ``(b1, b2)`` with closest point ``t0 + b1 (t1 - t0) + b2 (t2 - t0)``, from the
  feature type (vertex, edge by clamped projection, face by the plane projection);
- edge-edge: ``(s, t)`` with closest points ``ea0 + s (ea1 - ea0)`` and ``eb0 + t (eb1 - eb0)``;
  near-parallel edges use the closest endpoint-segment pair (exact for parallel segments).

Tangent bases ``T (n, d, d - 1)`` have orthonormal columns spanning the plane orthogonal to the
contact normal ``nh = (x_a - x_b) / |x_a - x_b|`` between the two closest points, which is the
direction of the distance gradient with respect to the first primitive. They are used lagged
(frozen during a friction solve), so no derivatives are provided. The first column is the
projection of the natural tangent of the pair onto that plane:

- point-point: 2D the normal rotated by +90 degrees; 3D any orthonormal pair;
- point-edge: the edge direction (2D: sign so that it points along e1 - e0; 3D: ``e_dir`` and
  ``nh x e_dir`` when the closest point is interior, as in IPC);
- point-triangle: ``t1 - t0`` and ``nh x (t1 - t0)``: the triangle's plane when the closest
  point is in the face;
- edge-edge: ``ea1 - ea0`` and ``nh x (ea1 - ea0)``.

Where the closest point is an endpoint / edge, the normal is not the feature normal, and the
natural tangent is projected (and re-normalised) so that the basis stays orthogonal to ``nh``.

Degenerate cases still get an orthonormal basis: when the two closest points coincide
(``|x_a - x_b| <= 1e-12 L``, ``L`` the pair's size) the normal falls back to the feature normal
(point-edge 3D: any direction orthogonal to the edge; triangle normal; ``a x b``), and when the
natural tangent is (anti)parallel to the normal any direction orthogonal to the normal is used.
"""

from __future__ import annotations

import numpy as np

from geometry._distance_kernels import KIND_EE, KIND_PT, _types
from geometry.distance import _stack

__all__ = [
    "edge_edge_closest_parameters",
    "edge_edge_tangent_basis",
    "point_edge_closest_parameter",
    "point_edge_tangent_basis",
    "point_point_tangent_basis",
    "point_triangle_closest_barycentric",
    "point_triangle_tangent_basis",
]

# Relative size below which a normal (or tangent) candidate counts as zero.
_REL_TOL = 1e-12


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


def _projection(p: np.ndarray, e0: np.ndarray, e1: np.ndarray) -> np.ndarray:
    """Clamped parameter (n,) of the projection of p onto segment e0-e1 (0 if degenerate)."""
    e = e1 - e0
    ee = _dot(e, e)
    lam = _dot(p - e0, e) / np.where(ee > 0.0, ee, 1.0)
    return np.clip(np.where(ee > 0.0, lam, 0.0), 0.0, 1.0)


def _cross_and_norm_sq(u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """n = u x v (n, 3) and |n|^2 (n,), 1 where it vanishes (a safe divisor)."""
    n = np.cross(u, v)
    m = _dot(n, n)
    return n, np.where(m > 0.0, m, 1.0)


def _size(V: np.ndarray) -> np.ndarray:
    """Size L (n,) of each pair: the largest distance of a vertex from the first one."""
    return np.linalg.norm(V[:, 1:] - V[:, :1], axis=2).max(axis=1)


# --------------------------------------------------------------------------- parameters
def point_edge_closest_parameter(p: np.ndarray, e0: np.ndarray, e1: np.ndarray) -> np.ndarray:
    """beta (n,) in [0, 1] of the closest point ``(1 - beta) e0 + beta e1`` of segment e0-e1 to p.

    Inputs (n, d) in m, d = 2 or 3; 0 for a zero-length edge.
    """
    V = _stack((p, e0, e1), ("p", "e0", "e1"), (2, 3))
    return _projection(V[:, 0], V[:, 1], V[:, 2])


def _pt_barycentric(V: np.ndarray) -> np.ndarray:
    p, t0, t1, t2 = V[:, 0], V[:, 1], V[:, 2], V[:, 3]
    typ = _types(V, KIND_PT)
    u, v, r = t1 - t0, t2 - t0, p - t0
    n, m = _cross_and_norm_sq(u, v)
    # Face: stable cross-product form of the plane projection's barycentric coordinates.
    face = np.stack([_dot(np.cross(r, v), n) / m, _dot(np.cross(u, r), n) / m], axis=1)
    l01 = _projection(p, t0, t1)
    l12 = _projection(p, t1, t2)
    l20 = _projection(p, t2, t0)
    zero, one = np.zeros_like(l01), np.ones_like(l01)
    conds = [typ == k for k in range(6)]
    b1 = np.select(conds, [zero, one, zero, l01, 1.0 - l12, zero], face[:, 0])
    b2 = np.select(conds, [zero, zero, one, zero, l12, 1.0 - l20], face[:, 1])
    return np.stack([b1, b2], axis=1)


def point_triangle_closest_barycentric(
    p: np.ndarray, t0: np.ndarray, t1: np.ndarray, t2: np.ndarray
) -> np.ndarray:
    """(b1, b2) (n, 2) of the closest point ``t0 + b1 (t1 - t0) + b2 (t2 - t0)`` of the triangle.

    Inputs (n, 3) in m. The coordinates satisfy ``b1, b2 >= 0``, ``b1 + b2 <= 1`` (up to
    round-off in the face case) and follow :func:`geometry.distance.point_triangle_type`.
    """
    V = _stack((p, t0, t1, t2), ("p", "t0", "t1", "t2"), (3,))
    return _pt_barycentric(V)


def _ee_parameters(V: np.ndarray) -> np.ndarray:
    a0, a1, b0, b1 = V[:, 0], V[:, 1], V[:, 2], V[:, 3]
    typ = _types(V, KIND_EE)
    a, b, r = a1 - a0, b1 - b0, b0 - a0
    n, m = _cross_and_norm_sq(a, b)
    # Interiors: closest points of the two lines (a x b != 0 for this type).
    s_ll = np.clip(_dot(np.cross(r, b), n) / m, 0.0, 1.0)
    t_ll = np.clip(_dot(np.cross(r, a), n) / m, 0.0, 1.0)
    zero, one = np.zeros_like(s_ll), np.ones_like(s_ll)
    conds = [typ == k for k in range(8)]
    s = np.select(
        conds,
        [zero, zero, one, one, _projection(b0, a0, a1), _projection(b1, a0, a1), zero, one],
        s_ll,
    )
    t = np.select(
        conds,
        [zero, one, zero, one, zero, one, _projection(a0, b0, b1), _projection(a1, b0, b1)],
        t_ll,
    )
    return np.stack([s, t], axis=1)


def edge_edge_closest_parameters(
    ea0: np.ndarray, ea1: np.ndarray, eb0: np.ndarray, eb1: np.ndarray
) -> np.ndarray:
    """(s, t) (n, 2) in [0, 1]^2 of the closest points of segments ea0-ea1 and eb0-eb1.

    Closest points ``ea0 + s (ea1 - ea0)`` and ``eb0 + t (eb1 - eb0)``; inputs (n, 3) in m.
    Parallel and degenerate edges take the closest endpoint-segment pair (no division by 0).
    """
    V = _stack((ea0, ea1, eb0, eb1), ("ea0", "ea1", "eb0", "eb1"), (3,))
    return _ee_parameters(V)


# --------------------------------------------------------------------------- bases
def _first_axis(n: int, dim: int) -> np.ndarray:
    """(n, dim) copies of the unit vector e_x: the fallback direction of degenerate pairs."""
    return np.tile(np.eye(dim)[0], (n, 1))


def _any_perpendicular(nh: np.ndarray) -> np.ndarray:
    """A unit vector (n, 3) orthogonal to the unit vectors nh (n, 3)."""
    axis = np.zeros_like(nh)
    axis[np.arange(nh.shape[0]), np.argmin(np.abs(nh), axis=1)] = 1.0
    t = np.cross(nh, axis)
    return t / np.linalg.norm(t, axis=1)[:, None]


def _unit_first(candidates: list[tuple[np.ndarray, np.ndarray]], last: np.ndarray) -> np.ndarray:
    """Per row, the first candidate vector whose norm exceeds its tolerance, normalised.

    ``candidates``: (vectors (n, d), tolerances (n,)); ``last`` (n, d): unit vectors to use when
    no candidate qualifies.
    """
    out = last.copy()
    done = np.zeros(last.shape[0], dtype=bool)
    for vec, tol in candidates:
        norm = np.linalg.norm(vec, axis=1)
        take = ~done & (norm > tol) & (norm > 0.0)
        out[take] = vec[take] / norm[take, None]
        done |= take
    return out


def _frame_3d(nh: np.ndarray, preferred: np.ndarray) -> np.ndarray:
    """Orthonormal (n, 3, 2) basis of the plane orthogonal to unit nh (n, 3), first column the
    projection of ``preferred`` (n, 3) onto that plane."""
    proj = preferred - _dot(preferred, nh)[:, None] * nh
    tol = _REL_TOL * np.linalg.norm(preferred, axis=1)
    t1 = _unit_first([(proj, tol)], _any_perpendicular(nh))
    t2 = np.cross(nh, t1)
    return np.ascontiguousarray(np.stack([t1, t2], axis=2))


def point_point_tangent_basis(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Tangent basis (n, d, d - 1) orthogonal to ``p - q``; p, q (n, d) in m, d = 2 or 3.

    Coincident points use the normal e_x. The basis is dimensionless (unit columns).
    """
    V = _stack((p, q), ("p", "q"), (2, 3))
    n, dim = V.shape[0], V.shape[2]
    ex = _first_axis(n, dim)
    nh = _unit_first([(V[:, 0] - V[:, 1], np.zeros(n))], ex)
    if dim == 2:
        return np.ascontiguousarray(np.stack([-nh[:, 1], nh[:, 0]], axis=1)[:, :, None])
    return _frame_3d(nh, np.zeros((n, 3)))


def point_edge_tangent_basis(p: np.ndarray, e0: np.ndarray, e1: np.ndarray) -> np.ndarray:
    """Tangent basis (n, d, d - 1) of point-segment pairs; inputs (n, d) in m, d = 2 or 3.

    Orthogonal to the normal from the closest point of the segment to p; first column along the
    edge when the closest point is interior (see the module doc for the other cases).
    """
    V = _stack((p, e0, e1), ("p", "e0", "e1"), (2, 3))
    n, dim = V.shape[0], V.shape[2]
    beta = _projection(V[:, 0], V[:, 1], V[:, 2])
    e = V[:, 2] - V[:, 1]
    normal = V[:, 0] - (V[:, 1] + beta[:, None] * e)
    tol = _REL_TOL * _size(V)
    ex = _first_axis(n, dim)
    if dim == 2:
        # Rotate the normal by -90 degrees; on the segment use the edge direction itself.
        rotated = np.stack([normal[:, 1], -normal[:, 0]], axis=1)
        t = _unit_first([(rotated, tol), (e, np.zeros(n))], ex)
        t *= np.where(_dot(t, e) < 0.0, -1.0, 1.0)[:, None]
        return np.ascontiguousarray(t[:, :, None])
    edge_dir = _unit_first([(e, np.zeros(n))], ex)
    nh = _unit_first([(normal, tol)], _any_perpendicular(edge_dir))
    return _frame_3d(nh, e)


def point_triangle_tangent_basis(
    p: np.ndarray, t0: np.ndarray, t1: np.ndarray, t2: np.ndarray
) -> np.ndarray:
    """Tangent basis (n, 3, 2) of point-triangle pairs; inputs (n, 3) in m.

    Spans the triangle's plane when the closest point is in the face; in general orthogonal to
    the normal from the closest point of the triangle to p.
    """
    V = _stack((p, t0, t1, t2), ("p", "t0", "t1", "t2"), (3,))
    n = V.shape[0]
    bary = _pt_barycentric(V)
    u, v = V[:, 2] - V[:, 1], V[:, 3] - V[:, 1]
    closest = V[:, 1] + bary[:, :1] * u + bary[:, 1:] * v
    tri_normal = np.cross(u, v)
    ex = _first_axis(n, 3)
    nh = _unit_first(
        [
            (V[:, 0] - closest, _REL_TOL * _size(V)),
            (tri_normal, _REL_TOL * np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1)),
        ],
        ex,
    )
    return _frame_3d(nh, np.where(_dot(u, u)[:, None] > 0.0, u, v))


def edge_edge_tangent_basis(
    ea0: np.ndarray, ea1: np.ndarray, eb0: np.ndarray, eb1: np.ndarray
) -> np.ndarray:
    """Tangent basis (n, 3, 2) of segment-segment pairs; inputs (n, 3) in m.

    Orthogonal to the normal between the closest points; first column along ``ea1 - ea0``
    (for interior closest points the plane of the two edge directions).
    """
    V = _stack((ea0, ea1, eb0, eb1), ("ea0", "ea1", "eb0", "eb1"), (3,))
    n = V.shape[0]
    st = _ee_parameters(V)
    a, b = V[:, 1] - V[:, 0], V[:, 3] - V[:, 2]
    gap = (V[:, 0] + st[:, :1] * a) - (V[:, 2] + st[:, 1:] * b)
    ex = _first_axis(n, 3)
    a_dir = _unit_first([(a, np.zeros(n)), (b, np.zeros(n))], ex)
    nh = _unit_first(
        [
            (gap, _REL_TOL * _size(V)),
            (np.cross(a, b), _REL_TOL * np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1)),
        ],
        _any_perpendicular(a_dir),
    )
    return _frame_3d(nh, a)
