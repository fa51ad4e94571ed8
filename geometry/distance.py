"""Unsigned distances between contact primitives, with closed-form gradients and Hessians.

Batched over ``n`` pairs: every argument is an array of shape ``(n, d)`` (metres), row ``i`` of
all arguments forming pair ``i``; ``d = 2`` or ``3`` comes from the data (point-point and
point-edge in 2D and 3D, point-triangle and edge-edge in 3D only).

- ``*_distance`` returns the unsigned distance ``d`` (n,) in m; ``*_distance_squared`` returns
  ``D = d^2`` in m^2 (smooth everywhere, which a barrier in ``D`` may prefer).
- ``*_gradient`` returns ``(n, k d)`` and ``*_hessian`` ``(n, k d, k d)`` for a pair of ``k``
  vertices, with respect to the flattened concatenation of the arguments in order (for
  point-edge: ``p`` then ``e0`` then ``e1``, each ``d`` components). Units: the gradient of
  ``d`` is dimensionless and its Hessian in 1/m; the gradient of ``D`` is in m and its Hessian
  dimensionless.
- ``*_type`` returns the closest-feature type (n,) int8 that selects the formula:

  point-edge:      0: e0, 1: e1, 2: edge interior (point-line);
  point-triangle:  0, 1, 2: vertex t0, t1, t2; 3: edge t0t1, 4: edge t1t2, 5: edge t2t0;
                   6: face interior (point-plane);
  edge-edge:       0: ea0-eb0, 1: ea0-eb1, 2: ea1-eb0, 3: ea1-eb1 (endpoint pairs);
                   4: edge a-eb0, 5: edge a-eb1, 6: ea0-edge b, 7: ea1-edge b (endpoint to
                   segment interior); 8: both interiors (line-line).

  Near-parallel edges (``|a x b|^2 <= 1e-20 |a|^2 |b|^2``, see :func:`edge_edge_parallel`) and
  degenerate (zero-length) edges take the closest of the four endpoint-to-segment distances,
  so they get a type in 0-7; that distance is exact for parallel segments. Degenerate triangles
  likewise take the closest of their three edges.

Each distance is that of the feature pair picked by its type (point-point, point-line,
point-plane, line-line), differentiated in closed form; see :mod:`geometry._distance_features`.
Derivatives are those of the smooth branch selected by the type, so across type boundaries the
gradient is continuous and the Hessian may jump. Where ``d = 0`` the unsigned distance is not
differentiable and the gradient and Hessian are returned as zero (an element of the
subdifferential); the squared versions are smooth there.
"""

from __future__ import annotations

import numpy as np

from geometry._distance_kernels import (
    KIND_EE,
    KIND_PE,
    KIND_PP,
    KIND_PT,
    PARALLEL_SIN2,
    _evaluate,
    _types,
)

__all__ = [
    "edge_edge_distance",
    "edge_edge_distance_gradient",
    "edge_edge_distance_hessian",
    "edge_edge_distance_squared",
    "edge_edge_distance_squared_gradient",
    "edge_edge_distance_squared_hessian",
    "edge_edge_parallel",
    "edge_edge_type",
    "point_edge_distance",
    "point_edge_distance_gradient",
    "point_edge_distance_hessian",
    "point_edge_distance_squared",
    "point_edge_distance_squared_gradient",
    "point_edge_distance_squared_hessian",
    "point_edge_type",
    "point_point_distance",
    "point_point_distance_gradient",
    "point_point_distance_hessian",
    "point_point_distance_squared",
    "point_point_distance_squared_gradient",
    "point_point_distance_squared_hessian",
    "point_triangle_distance",
    "point_triangle_distance_gradient",
    "point_triangle_distance_hessian",
    "point_triangle_distance_squared",
    "point_triangle_distance_squared_gradient",
    "point_triangle_distance_squared_hessian",
    "point_triangle_type",
]

_NAMES = {
    KIND_PP: ("p", "q"),
    KIND_PE: ("p", "e0", "e1"),
    KIND_PT: ("p", "t0", "t1", "t2"),
    KIND_EE: ("ea0", "ea1", "eb0", "eb1"),
}
_DIMS = {KIND_PP: (2, 3), KIND_PE: (2, 3), KIND_PT: (3,), KIND_EE: (3,)}


def _stack_pairs(kind: int, arrays: tuple[np.ndarray, ...], names: tuple[str, ...]) -> np.ndarray:
    """The ``(n, d)`` vertex arrays of a batch of ``kind`` stacked (:func:`_stack`; d = 2 or 3 for
    point-point/point-edge, 3 otherwise)."""
    return _stack(arrays, names, _DIMS[kind])


def _stack(
    arrays: tuple[np.ndarray, ...], names: tuple[str, ...], dims: tuple[int, ...]
) -> np.ndarray:
    """Validate the ``(n, d)`` vertex arrays of a batch and stack them to ``(n, k, d)`` float64.

    Raises ValueError naming the argument that is not 2D, has another shape than the first one,
    a dimension ``d`` not in ``dims``, or non-finite entries (with the first offending row).
    """
    arrs = [np.asarray(a, dtype=np.float64) for a in arrays]
    ref = arrs[0]
    if ref.ndim != 2 or ref.shape[1] not in dims:
        allowed = " or ".join(str(d) for d in dims)
        raise ValueError(f"{names[0]} must have shape (n, {allowed}), got {ref.shape}")
    for name, a in zip(names, arrs, strict=True):
        if a.shape != ref.shape:
            raise ValueError(f"{name} must have shape {ref.shape} like {names[0]}, got {a.shape}")
        bad = ~np.isfinite(a).all(axis=1)
        if bad.any():
            raise ValueError(f"{name} has non-finite entries in rows {np.flatnonzero(bad)[:10]}")
    return np.ascontiguousarray(np.stack(arrs, axis=1))


def _run(kind: int, arrays: tuple[np.ndarray, ...], squared: bool, order: int) -> np.ndarray:
    value, grad, hess = _evaluate(_stack_pairs(kind, arrays, _NAMES[kind]), kind, squared, order)
    return (value, grad, hess)[order]


# --------------------------------------------------------------------------- point-point
def point_point_distance(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """|p - q| (n,) in m of points p, q (n, d)."""
    return _run(KIND_PP, (p, q), False, 0)


def point_point_distance_gradient(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Gradient (n, 2d) of |p - q| w.r.t. (p, q); p, q (n, d) in m."""
    return _run(KIND_PP, (p, q), False, 1)


def point_point_distance_hessian(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hessian (n, 2d, 2d) in 1/m of |p - q| w.r.t. (p, q); p, q (n, d) in m."""
    return _run(KIND_PP, (p, q), False, 2)


def point_point_distance_squared(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """|p - q|^2 (n,) in m^2 of points p, q (n, d) in m."""
    return _run(KIND_PP, (p, q), True, 0)


def point_point_distance_squared_gradient(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Gradient (n, 2d) in m of |p - q|^2 w.r.t. (p, q); p, q (n, d) in m."""
    return _run(KIND_PP, (p, q), True, 1)


def point_point_distance_squared_hessian(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hessian (n, 2d, 2d) of |p - q|^2 w.r.t. (p, q); p, q (n, d) in m."""
    return _run(KIND_PP, (p, q), True, 2)


# --------------------------------------------------------------------------- point-edge
def point_edge_type(p: np.ndarray, e0: np.ndarray, e1: np.ndarray) -> np.ndarray:
    """Closest feature (n,) int8 of segment e0-e1 to p (0: e0, 1: e1, 2: interior); (n, d) in m."""
    return _types(_stack_pairs(KIND_PE, (p, e0, e1), _NAMES[KIND_PE]), KIND_PE)


def point_edge_distance(p: np.ndarray, e0: np.ndarray, e1: np.ndarray) -> np.ndarray:
    """Distance (n,) in m from points p to segments e0-e1; all (n, d) in m, d = 2 or 3."""
    return _run(KIND_PE, (p, e0, e1), False, 0)


def point_edge_distance_gradient(p: np.ndarray, e0: np.ndarray, e1: np.ndarray) -> np.ndarray:
    """Gradient (n, 3d) of the point-segment distance w.r.t. (p, e0, e1); inputs (n, d) in m."""
    return _run(KIND_PE, (p, e0, e1), False, 1)


def point_edge_distance_hessian(p: np.ndarray, e0: np.ndarray, e1: np.ndarray) -> np.ndarray:
    """Hessian (n, 3d, 3d) in 1/m of the point-segment distance; inputs (n, d) in m."""
    return _run(KIND_PE, (p, e0, e1), False, 2)


def point_edge_distance_squared(p: np.ndarray, e0: np.ndarray, e1: np.ndarray) -> np.ndarray:
    """Squared distance (n,) in m^2 from points p to segments e0-e1; inputs (n, d) in m."""
    return _run(KIND_PE, (p, e0, e1), True, 0)


def point_edge_distance_squared_gradient(
    p: np.ndarray, e0: np.ndarray, e1: np.ndarray
) -> np.ndarray:
    """Gradient (n, 3d) in m of the squared point-segment distance; inputs (n, d) in m."""
    return _run(KIND_PE, (p, e0, e1), True, 1)


def point_edge_distance_squared_hessian(
    p: np.ndarray, e0: np.ndarray, e1: np.ndarray
) -> np.ndarray:
    """Hessian (n, 3d, 3d) of the squared point-segment distance; inputs (n, d) in m."""
    return _run(KIND_PE, (p, e0, e1), True, 2)


# --------------------------------------------------------------------------- point-triangle
def point_triangle_type(
    p: np.ndarray, t0: np.ndarray, t1: np.ndarray, t2: np.ndarray
) -> np.ndarray:
    """Closest feature (n,) int8 of triangle t0t1t2 to p (codes in the module doc); (n, 3) in m."""
    return _types(_stack_pairs(KIND_PT, (p, t0, t1, t2), _NAMES[KIND_PT]), KIND_PT)


def point_triangle_distance(
    p: np.ndarray, t0: np.ndarray, t1: np.ndarray, t2: np.ndarray
) -> np.ndarray:
    """Distance (n,) in m from points p to triangles t0t1t2; all (n, 3) in m."""
    return _run(KIND_PT, (p, t0, t1, t2), False, 0)


def point_triangle_distance_gradient(
    p: np.ndarray, t0: np.ndarray, t1: np.ndarray, t2: np.ndarray
) -> np.ndarray:
    """Gradient (n, 12) of the point-triangle distance w.r.t. (p, t0, t1, t2); (n, 3) in m."""
    return _run(KIND_PT, (p, t0, t1, t2), False, 1)


def point_triangle_distance_hessian(
    p: np.ndarray, t0: np.ndarray, t1: np.ndarray, t2: np.ndarray
) -> np.ndarray:
    """Hessian (n, 12, 12) in 1/m of the point-triangle distance; inputs (n, 3) in m."""
    return _run(KIND_PT, (p, t0, t1, t2), False, 2)


def point_triangle_distance_squared(
    p: np.ndarray, t0: np.ndarray, t1: np.ndarray, t2: np.ndarray
) -> np.ndarray:
    """Squared distance (n,) in m^2 from points p to triangles t0t1t2; (n, 3) in m."""
    return _run(KIND_PT, (p, t0, t1, t2), True, 0)


def point_triangle_distance_squared_gradient(
    p: np.ndarray, t0: np.ndarray, t1: np.ndarray, t2: np.ndarray
) -> np.ndarray:
    """Gradient (n, 12) in m of the squared point-triangle distance; inputs (n, 3) in m."""
    return _run(KIND_PT, (p, t0, t1, t2), True, 1)


def point_triangle_distance_squared_hessian(
    p: np.ndarray, t0: np.ndarray, t1: np.ndarray, t2: np.ndarray
) -> np.ndarray:
    """Hessian (n, 12, 12) of the squared point-triangle distance; inputs (n, 3) in m."""
    return _run(KIND_PT, (p, t0, t1, t2), True, 2)


# --------------------------------------------------------------------------- edge-edge
def edge_edge_parallel(
    ea0: np.ndarray, ea1: np.ndarray, eb0: np.ndarray, eb1: np.ndarray
) -> np.ndarray:
    """Whether (n,) bool segments ea0-ea1 and eb0-eb1 are treated as parallel (or degenerate).

    True where ``|a x b|^2 <= 1e-20 |a|^2 |b|^2`` with ``a = ea1 - ea0``, ``b = eb1 - eb0``;
    inputs (n, 3) in m. Such pairs use the closest endpoint-to-segment distance (types 0-7).
    """
    V = _stack_pairs(KIND_EE, (ea0, ea1, eb0, eb1), _NAMES[KIND_EE])
    a = V[:, 1] - V[:, 0]
    b = V[:, 3] - V[:, 2]
    n = np.cross(a, b)
    aa = np.einsum("ij,ij->i", a, a)
    bb = np.einsum("ij,ij->i", b, b)
    return np.einsum("ij,ij->i", n, n) <= PARALLEL_SIN2 * aa * bb


def edge_edge_type(
    ea0: np.ndarray, ea1: np.ndarray, eb0: np.ndarray, eb1: np.ndarray
) -> np.ndarray:
    """Closest feature pair (n,) int8 of segments ea0-ea1 and eb0-eb1 (codes in the module doc).

    Inputs (n, 3) in m. Parallel pairs get the type of their closest endpoint-segment pair.
    """
    return _types(_stack_pairs(KIND_EE, (ea0, ea1, eb0, eb1), _NAMES[KIND_EE]), KIND_EE)


def edge_edge_distance(
    ea0: np.ndarray, ea1: np.ndarray, eb0: np.ndarray, eb1: np.ndarray
) -> np.ndarray:
    """Distance (n,) in m between segments ea0-ea1 and eb0-eb1; all (n, 3) in m."""
    return _run(KIND_EE, (ea0, ea1, eb0, eb1), False, 0)


def edge_edge_distance_gradient(
    ea0: np.ndarray, ea1: np.ndarray, eb0: np.ndarray, eb1: np.ndarray
) -> np.ndarray:
    """Gradient (n, 12) of the segment-segment distance w.r.t. (ea0, ea1, eb0, eb1); (n, 3) m."""
    return _run(KIND_EE, (ea0, ea1, eb0, eb1), False, 1)


def edge_edge_distance_hessian(
    ea0: np.ndarray, ea1: np.ndarray, eb0: np.ndarray, eb1: np.ndarray
) -> np.ndarray:
    """Hessian (n, 12, 12) in 1/m of the segment-segment distance; inputs (n, 3) in m."""
    return _run(KIND_EE, (ea0, ea1, eb0, eb1), False, 2)


def edge_edge_distance_squared(
    ea0: np.ndarray, ea1: np.ndarray, eb0: np.ndarray, eb1: np.ndarray
) -> np.ndarray:
    """Squared distance (n,) in m^2 between segments ea0-ea1 and eb0-eb1; (n, 3) in m."""
    return _run(KIND_EE, (ea0, ea1, eb0, eb1), True, 0)


def edge_edge_distance_squared_gradient(
    ea0: np.ndarray, ea1: np.ndarray, eb0: np.ndarray, eb1: np.ndarray
) -> np.ndarray:
    """Gradient (n, 12) in m of the squared segment-segment distance; inputs (n, 3) in m."""
    return _run(KIND_EE, (ea0, ea1, eb0, eb1), True, 1)


def edge_edge_distance_squared_hessian(
    ea0: np.ndarray, ea1: np.ndarray, eb0: np.ndarray, eb1: np.ndarray
) -> np.ndarray:
    """Hessian (n, 12, 12) of the squared segment-segment distance; inputs (n, 3) in m."""
    return _run(KIND_EE, (ea0, ea1, eb0, eb1), True, 2)
