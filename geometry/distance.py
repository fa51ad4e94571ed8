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

from collections.abc import Callable

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


# The 24 public functions ``{pair}_distance[_squared][_gradient|_hessian](*vertices)`` are made
# from these tables: the pair's kind, its vertices' dimension and what it measures; the result.
_PAIRS = {
    "point_point": (KIND_PP, "d", "points p and q"),
    "point_edge": (KIND_PE, "d", "points p and segments e0-e1"),
    "point_triangle": (KIND_PT, "3", "points p and triangles t0t1t2"),
    "edge_edge": (KIND_EE, "3", "segments ea0-ea1 and eb0-eb1"),
}
_RESULTS = {  # (squared, order): what is returned, with its shape and unit
    (False, 0): "Distance (n,) in m",
    (False, 1): "Gradient (n, {kd}) of the distance",
    (False, 2): "Hessian (n, {kd}, {kd}) in 1/m of the distance",
    (True, 0): "Squared distance (n,) in m^2",
    (True, 1): "Gradient (n, {kd}) in m of the squared distance",
    (True, 2): "Hessian (n, {kd}, {kd}) of the squared distance",
}


def _distance_function(pair: str, squared: bool, order: int) -> Callable[..., np.ndarray]:
    """The public function of ``pair`` (a key of ``_PAIRS``) for ``squared`` and ``order``."""
    kind, d, what = _PAIRS[pair]
    names = _NAMES[kind]
    name = (
        f"{pair}_distance" + ("_squared" if squared else "") + ("", "_gradient", "_hessian")[order]
    )

    def function(*vertices: np.ndarray) -> np.ndarray:
        if len(vertices) != len(names):
            raise TypeError(f"{name} takes {len(names)} arrays {names}, got {len(vertices)}")
        return _run(kind, vertices, squared, order)

    kd = f"{len(names)}d" if d == "d" else str(3 * len(names))
    result = _RESULTS[(squared, order)].format(kd=kd)
    function.__name__ = function.__qualname__ = name
    function.__doc__ = f"{result} between {what}, w.r.t. {names}; each (n, {d}) in m."
    return function


_DISTANCES = [_distance_function(pair, *key) for pair in _PAIRS for key in _RESULTS]
globals().update((f.__name__, f) for f in _DISTANCES)
__all__ = sorted(
    [f.__name__ for f in _DISTANCES]
    + ["edge_edge_parallel", "edge_edge_type", "point_edge_type", "point_triangle_type"]
)


# --------------------------------------------------------------------------- point-edge
def point_edge_type(p: np.ndarray, e0: np.ndarray, e1: np.ndarray) -> np.ndarray:
    """Closest feature (n,) int8 of segment e0-e1 to p (0: e0, 1: e1, 2: interior); (n, d) in m."""
    return _types(_stack_pairs(KIND_PE, (p, e0, e1), _NAMES[KIND_PE]), KIND_PE)


# --------------------------------------------------------------------------- point-triangle
def point_triangle_type(
    p: np.ndarray, t0: np.ndarray, t1: np.ndarray, t2: np.ndarray
) -> np.ndarray:
    """Closest feature (n,) int8 of triangle t0t1t2 to p (codes in the module doc); (n, 3) in m."""
    return _types(_stack_pairs(KIND_PT, (p, t0, t1, t2), _NAMES[KIND_PT]), KIND_PT)


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
