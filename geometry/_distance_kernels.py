"""numba kernels of :mod:`geometry.distance` and :mod:`geometry.ccd`: closest-feature
classification and the batched distance driver.

Private: array-in / array-out, no validation. A batch of primitive pairs is one array
``V (n, nv, dim)`` (the pair's vertices in argument order) and a ``kind``:

==========  ====  ============================  ==========================================
kind        nv    vertices                      closest-feature types
==========  ====  ============================  ==========================================
KIND_PP     2     p, q                          0
KIND_PE     3     p, e0, e1                     0: e0, 1: e1, 2: edge interior
KIND_PT     4     p, t0, t1, t2                 0-2: vertex t0-t2, 3: edge t0t1, 4: t1t2,
                                                5: t2t0, 6: face interior
KIND_EE     4     a0, a1, b0, b1                0: a0-b0, 1: a0-b1, 2: a1-b0, 3: a1-b1,
                                                4: edge a-b0, 5: a-b1, 6: a0-edge b,
                                                7: a1-edge b, 8: edge-edge interiors
==========  ====  ============================  ==========================================

Classification is by convexity: the squared distance between a point and a triangle (or between
two segments) is a convex function of the barycentric parameters; if its unconstrained
minimiser (projection onto the plane, closest points of the two lines) lies inside the parameter
domain it is the answer, otherwise the minimum lies on the domain boundary, i.e. it is the
smallest of the point-edge distances to the triangle's three edges (of the four endpoint-segment
distances). That boundary search needs no special cases and is also the fallback for
near-parallel edges and degenerate triangles (``|u x v|^2 <= 1e-20 |u|^2 |v|^2``): there the
closest points of the lines are ill-defined, but the boundary minimum is exact for parallel
segments. Interior tests use the stable cross-product forms of the parameters, e.g. for edges
``s = ((r x b).n) / n.n``, ``-t = ((a x r).n) / n.n`` with ``n = a x b``, ``r = b0 - a0``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from geometry._distance_features import (
    _NA,
    FEAT_LL,
    FEAT_PL,
    FEAT_PLANE,
    FEAT_PP,
    _differences,
    _feature,
    _finish,
    _scatter,
)

KIND_PP = 0
KIND_PE = 1
KIND_PT = 2
KIND_EE = 3

# sin^2 of the angle below which two edges count as parallel / a triangle as degenerate.
PARALLEL_SIN2 = 1e-20

# Feature and local-to-pair vertex slots of each (kind, type).
_FEATURE = np.full((4, 9), -1, dtype=np.int64)
_BLOCKS = np.zeros((4, 9, 4), dtype=np.int64)


def _set(kind: int, typ: int, feat: int, blocks: tuple[int, ...]) -> None:
    _FEATURE[kind, typ] = feat
    _BLOCKS[kind, typ, : len(blocks)] = blocks


_set(KIND_PP, 0, FEAT_PP, (0, 1))
for _t, _b in enumerate([(0, 1), (0, 2), (0, 1, 2)]):
    _set(KIND_PE, _t, FEAT_PL if _t == 2 else FEAT_PP, _b)
for _t, _b in enumerate([(0, 1), (0, 2), (0, 3), (0, 1, 2), (0, 2, 3), (0, 3, 1), (0, 1, 2, 3)]):
    _set(KIND_PT, _t, (FEAT_PP, FEAT_PL, FEAT_PLANE)[min(_t // 3, 2)], _b)
for _t, _b in enumerate(
    [(0, 2), (0, 3), (1, 2), (1, 3), (2, 0, 1), (3, 0, 1), (0, 2, 3), (1, 2, 3), (0, 1, 2, 3)]
):
    _set(KIND_EE, _t, (FEAT_PP, FEAT_PL, FEAT_LL)[min(_t // 4, 2)], _b)

# Boundary candidates (point, edge start, edge end) as the pair's vertex slots, and the
# point-edge type (0: e0, 1: e1, 2: interior) of each -> pair type.
# Point-triangle: p vs the triangle edges (t0, t1), (t1, t2), (t2, t0).
_PT_CAND_VERTS = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 1]], dtype=np.int64)
_PT_EDGE_TYPE = np.array([[0, 1, 3], [1, 2, 4], [2, 0, 5]], dtype=np.int64)
# Edge-edge: b0 vs edge a, b1 vs edge a, a0 vs edge b, a1 vs edge b.
_EE_CAND_TYPE = np.array([[0, 2, 4], [1, 3, 5], [0, 1, 6], [2, 3, 7]], dtype=np.int64)
_EE_CAND_VERTS = np.array([[2, 0, 1], [3, 0, 1], [0, 2, 3], [1, 2, 3]], dtype=np.int64)


@njit(cache=True)
def _sq_dist(p: np.ndarray, q: np.ndarray) -> float:
    """|p - q|^2 for two (dim,) points."""
    D = 0.0
    for c in range(p.shape[0]):
        w = p[c] - q[c]
        D += w * w
    return D


@njit(cache=True)
def _pe_classify(p: np.ndarray, e0: np.ndarray, e1: np.ndarray) -> tuple[int, float]:
    """Point-segment closest-feature type and squared distance; (dim,) points."""
    a = 0.0
    b = 0.0
    for c in range(p.shape[0]):
        e = e1[c] - e0[c]
        a += (p[c] - e0[c]) * e
        b += e * e
    if b <= 0.0 or a <= 0.0:
        return 0, _sq_dist(p, e0)
    if a >= b:
        return 1, _sq_dist(p, e1)
    lam = a / b
    D = 0.0
    for c in range(p.shape[0]):
        w = (p[c] - e0[c]) - lam * (e1[c] - e0[c])
        D += w * w
    return 2, D


@njit(cache=True)
def _sub(a: np.ndarray, b: np.ndarray) -> tuple[float, float, float]:
    return a[0] - b[0], a[1] - b[1], a[2] - b[2]


@njit(cache=True)
def _cross(
    a: tuple[float, float, float], b: tuple[float, float, float]
) -> tuple[float, float, float]:
    return a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]


@njit(cache=True)
def _dot(a: tuple[float, float, float], b: tuple[float, float, float]) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True)
def _plane_coords(
    u: tuple[float, float, float], v: tuple[float, float, float], r: tuple[float, float, float]
) -> tuple[float, float, float]:
    """``(a, b, D)``: r's projection onto the plane of u and v is ``a u + b v`` (cross-product
    forms), D its squared distance to the plane; ``(nan, nan, inf)`` for parallel u and v."""
    n = _cross(u, v)
    m = _dot(n, n)
    if not m > PARALLEL_SIN2 * _dot(u, u) * _dot(v, v):
        return np.nan, np.nan, np.inf
    rn = _dot(r, n)
    return _dot(_cross(r, v), n) / m, _dot(_cross(u, r), n) / m, rn * rn / m


@njit(cache=True)
def _boundary_min(X: np.ndarray, verts: np.ndarray, types: np.ndarray) -> tuple[int, float]:
    """Type and squared distance of the closest of the point-edge candidates ``verts (k, 3)``
    (slots of X); ``types (k, 3)`` maps each one's point-edge type to the pair's."""
    best_t = -1
    best_D = np.inf
    for k in range(verts.shape[0]):
        iv = verts[k]
        t, D = _pe_classify(X[iv[0]], X[iv[1]], X[iv[2]])
        if D < best_D:
            best_D = D
            best_t = types[k, t]
    return best_t, best_D


@njit(cache=True)
def _pt_classify(X: np.ndarray) -> tuple[int, float]:
    """Point-triangle type and squared distance; X (4, 3) = (p, t0, t1, t2)."""
    # (b1, b2): barycentric coordinates of p's projection onto the triangle's plane.
    b1, b2, D = _plane_coords(_sub(X[2], X[1]), _sub(X[3], X[1]), _sub(X[0], X[1]))
    if b1 >= 0.0 and b2 >= 0.0 and b1 + b2 <= 1.0:
        return 6, D
    return _boundary_min(X, _PT_CAND_VERTS, _PT_EDGE_TYPE)


@njit(cache=True)
def _ee_classify(X: np.ndarray) -> tuple[int, float]:
    """Segment-segment type and squared distance; X (4, 3) = (a0, a1, b0, b1)."""
    # The closest points a0 + s a and b0 + t b of the two lines: r = b0 - a0 has the plane
    # coordinates (s, -t) in the basis (a, b).
    s, minus_t, D = _plane_coords(_sub(X[1], X[0]), _sub(X[3], X[2]), _sub(X[2], X[0]))
    if 0.0 <= s <= 1.0 and -1.0 <= minus_t <= 0.0:
        return 8, D
    return _boundary_min(X, _EE_CAND_VERTS, _EE_CAND_TYPE)


@njit(cache=True)
def _classify(X: np.ndarray, kind: int) -> tuple[int, float]:
    """Closest-feature type and squared distance of one pair X (nv, dim) of the given kind."""
    if kind == KIND_PP:
        return 0, _sq_dist(X[0], X[1])
    if kind == KIND_PE:
        return _pe_classify(X[0], X[1], X[2])
    if kind == KIND_PT:
        return _pt_classify(X)
    return _ee_classify(X)


@njit(cache=True)
def _types(V: np.ndarray, kind: int) -> np.ndarray:
    """Closest-feature types (n,) int8 of the pairs V (n, nv, dim)."""
    out = np.empty(V.shape[0], dtype=np.int8)
    for i in range(V.shape[0]):
        out[i] = _classify(V[i], kind)[0]
    return out


@njit(cache=True)
def _pair_derivatives(
    X: np.ndarray,
    kind: int,
    squared: bool,
    order: int,
    y: np.ndarray,
    gy: np.ndarray,
    Hy: np.ndarray,
) -> tuple[float, int]:
    """d (or D) of one pair X (nv, dim) and its closest-feature type; with ``order`` >= 1 (2)
    the gradient (Hessian) w.r.t. the feature's difference vectors in gy[:na dim]
    (Hy[:na dim, :na dim]), na = _NA[feature]; ``_scatter`` pulls them back to the pair's
    vertices. y (3, dim), gy (3 dim,), Hy (3 dim, 3 dim) are workspace / output."""
    typ, D = _classify(X, kind)
    feat = _FEATURE[kind, typ]
    _differences(feat, X, _BLOCKS[kind, typ], y)
    q = _feature(feat, y, gy, Hy, order)
    return _finish(q, feat >= FEAT_PLANE, squared, gy, Hy, _NA[feat] * X.shape[1], order), typ


@njit(cache=True)
def _evaluate(
    V: np.ndarray, kind: int, squared: bool, order: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distances (n,), gradients (n, nv dim) and Hessians (n, nv dim, nv dim) of pairs V.

    ``squared`` selects D = d^2 instead of d; ``order`` 0, 1, 2 selects how many derivatives
    are computed (the arrays of the others have zero rows). Serial: a parallel loop doubled
    the compile time for little gain (filling the Hessian array is memory-bound).
    """
    n, nv, dim = V.shape
    nx = nv * dim
    value = np.empty(n)
    grad = np.zeros((n if order >= 1 else 0, nx))
    hess = np.zeros((n if order >= 2 else 0, nx, nx))
    y = np.empty((3, dim))
    gy = np.empty(3 * dim)
    Hy = np.empty((3 * dim, 3 * dim))
    no_hess = np.empty((0, 0))
    for i in range(n):
        if order == 0:
            D = _classify(V[i], kind)[1]
            value[i] = D if squared else math.sqrt(D)
            continue
        value[i], typ = _pair_derivatives(V[i], kind, squared, order, y, gy, Hy)
        feat = _FEATURE[kind, typ]
        blocks = _BLOCKS[kind, typ]
        if order >= 2:
            _scatter(feat, blocks, dim, gy, Hy, grad[i], hess[i], order)
        else:
            _scatter(feat, blocks, dim, gy, Hy, grad[i], no_hess, order)
    return value, grad, hess
