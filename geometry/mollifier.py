"""IPC's edge-edge mollifier, which smooths the edge-edge barrier where two edges turn parallel.

For segments ``ea0-ea1`` and ``eb0-eb1`` with ``a = ea1 - ea0`` and ``b = eb1 - eb0``::

    c     = |a x b|^2 = |a|^2 |b|^2 - (a.b)^2                      (m^4)
    m(c)  = -c^2 / eps_x^2 + 2 c / eps_x    for c < eps_x,   1 otherwise
    eps_x = 1e-3 |a^0|^2 |b^0|^2                                    (rest lengths, m^4)

``m`` rises from 0 (parallel edges) to 1 with ``m'(eps_x) = 0``, so it is C1 at ``eps_x`` (its
second derivative jumps from ``-2 / eps_x^2`` to 0). The mollified edge-edge barrier is
``m(c) b(d)``. Derivatives by the chain rule on ``c``::

    grad m = m'(c) grad c,      hess m = m''(c) grad c grad c^T + m'(c) hess c
    dc/da  = 2 b x (a x b) = 2 (|b|^2 a - (a.b) b),      dc/db = 2 (|a|^2 b - (a.b) a)
    d2c/da2 = 2 (|b|^2 I - b b^T),  d2c/db2 = 2 (|a|^2 I - a a^T),
    d2c/da db = 2 (2 a b^T - b a^T - (a.b) I)

and ``a``, ``b`` are differences of the vertices (``da/dea0 = -I``, ``da/dea1 = I``, ...).
Gradients ``(n, 12)`` (1/m) and Hessians ``(n, 12, 12)`` (1/m^2) are with respect to the
flattened ``(ea0, ea1, eb0, eb1)``, the vertex order of :mod:`geometry.distance`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from geometry.distance import _stack

__all__ = [
    "edge_edge_mollifier",
    "edge_edge_mollifier_gradient",
    "edge_edge_mollifier_hessian",
    "edge_edge_mollifier_threshold",
]

_NAMES = ("ea0", "ea1", "eb0", "eb1")


def _check_eps(eps_x: np.ndarray, n: int) -> np.ndarray:
    eps_x = np.ascontiguousarray(eps_x, dtype=np.float64)
    if eps_x.shape != (n,):
        raise ValueError(f"eps_x must have shape ({n},) like the edges, got {eps_x.shape}")
    bad = ~(np.isfinite(eps_x) & (eps_x > 0.0))
    if bad.any():
        raise ValueError(f"eps_x must be positive and finite; bad rows {np.flatnonzero(bad)[:10]}")
    return eps_x


@njit(cache=True)
def _evaluate(X: np.ndarray, eps_x: np.ndarray, order: int) -> tuple:
    """Mollifier values (n,), gradients (n, 12) and (if order == 2) Hessians (n, 12, 12) of the
    edge pairs X (n, 4, 3); unused outputs are returned empty."""
    n = X.shape[0]
    value = np.ones(n)
    grad = np.zeros((n if order >= 1 else 0, 12))
    hess = np.zeros((n if order >= 2 else 0, 12, 12))
    a = np.empty(3)
    b = np.empty(3)
    cr = np.empty(3)
    ga = np.empty(3)
    gb = np.empty(3)
    g = np.empty(12)
    sign = np.array([-1.0, 1.0, -1.0, 1.0])
    for i in range(n):
        for k in range(3):
            a[k] = X[i, 1, k] - X[i, 0, k]
            b[k] = X[i, 3, k] - X[i, 2, k]
        cr[0] = a[1] * b[2] - a[2] * b[1]
        cr[1] = a[2] * b[0] - a[0] * b[2]
        cr[2] = a[0] * b[1] - a[1] * b[0]
        c = cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]
        eps = eps_x[i]
        if c >= eps:
            continue
        x = c / eps
        value[i] = (2.0 - x) * x
        if order == 0:
            continue
        m1 = 2.0 * (1.0 - x) / eps
        aa = a[0] * a[0] + a[1] * a[1] + a[2] * a[2]
        bb = b[0] * b[0] + b[1] * b[1] + b[2] * b[2]
        ab = a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
        for k in range(3):
            ga[k] = 2.0 * (bb * a[k] - ab * b[k])
            gb[k] = 2.0 * (aa * b[k] - ab * a[k])
        for v in range(4):
            src = ga if v < 2 else gb
            for k in range(3):
                g[3 * v + k] = sign[v] * src[k]
                grad[i, 3 * v + k] = m1 * g[3 * v + k]
        if order == 1:
            continue
        m2 = -2.0 / (eps * eps)
        for r in range(12):
            for s in range(12):
                hess[i, r, s] = m2 * g[r] * g[s]
        # m'(c) times the Hessian of c, block by block over the vertex pairs (v, w).
        for v in range(4):
            for w in range(4):
                sw = sign[v] * sign[w]
                for k in range(3):
                    for l in range(3):
                        delta = 1.0 if k == l else 0.0
                        if v < 2 and w < 2:
                            h = 2.0 * (bb * delta - b[k] * b[l])
                        elif v >= 2 and w >= 2:
                            h = 2.0 * (aa * delta - a[k] * a[l])
                        elif v < 2:
                            h = 2.0 * (2.0 * a[k] * b[l] - b[k] * a[l] - ab * delta)
                        else:
                            h = 2.0 * (2.0 * b[k] * a[l] - a[k] * b[l] - ab * delta)
                        hess[i, 3 * v + k, 3 * w + l] += m1 * sw * h
    return value, grad, hess


def _run(arrays: tuple[np.ndarray, ...], eps_x: np.ndarray, order: int) -> np.ndarray:
    X = _stack(arrays, _NAMES, (3,))
    return _evaluate(X, _check_eps(eps_x, X.shape[0]), order)[order]


def edge_edge_mollifier_threshold(
    ea0: np.ndarray, ea1: np.ndarray, eb0: np.ndarray, eb1: np.ndarray
) -> np.ndarray:
    """eps_x (n,) in m^4 = 1e-3 |ea1 - ea0|^2 |eb1 - eb0|^2 of REST positions (n, 3) in m."""
    X = _stack((ea0, ea1, eb0, eb1), _NAMES, (3,))
    a = X[:, 1] - X[:, 0]
    b = X[:, 3] - X[:, 2]
    return 1e-3 * np.einsum("ij,ij->i", a, a) * np.einsum("ij,ij->i", b, b)


def edge_edge_mollifier(
    ea0: np.ndarray, ea1: np.ndarray, eb0: np.ndarray, eb1: np.ndarray, eps_x: np.ndarray
) -> np.ndarray:
    """Mollifier m (n,) in [0, 1] of segment pairs (n, 3) in m with thresholds eps_x (n,) in m^4."""
    return _run((ea0, ea1, eb0, eb1), eps_x, 0)


def edge_edge_mollifier_gradient(
    ea0: np.ndarray, ea1: np.ndarray, eb0: np.ndarray, eb1: np.ndarray, eps_x: np.ndarray
) -> np.ndarray:
    """Gradient (n, 12) in 1/m of the mollifier w.r.t. (ea0, ea1, eb0, eb1); inputs (n, 3) in m,
    eps_x (n,) in m^4. Zero where ``c >= eps_x``."""
    return _run((ea0, ea1, eb0, eb1), eps_x, 1)


def edge_edge_mollifier_hessian(
    ea0: np.ndarray, ea1: np.ndarray, eb0: np.ndarray, eb1: np.ndarray, eps_x: np.ndarray
) -> np.ndarray:
    """Hessian (n, 12, 12) in 1/m^2 of the mollifier w.r.t. (ea0, ea1, eb0, eb1); inputs
    (n, 3) in m, eps_x (n,) in m^4. Zero where ``c >= eps_x``."""
    return _run((ea0, ea1, eb0, eb1), eps_x, 2)
