"""numba kernels of :mod:`geometry.ccd`: additive continuous collision detection (ACCD).

Private: array-in / array-out, no validation. Additive CCD (Li, Kaufman, Jiang 2021,
"Codimensional Incremental Potential Contact", Alg. 1) for one pair with vertices
``X0 (nv, dim)`` moving linearly by ``dX (nv, dim)``: ``x_k(t) = X0_k + t dX_k``.

The distance is invariant under a common translation, so the mean displacement is removed:
``P_k = dX_k - mean(dX)``. The distance between the two sides (side A: the first ``n_a``
vertices, side B: the rest) is the distance between two convex hulls whose vertices move with
speeds at most ``|P_k|``, so it is Lipschitz in time with constant

    l_p = max_{k in A} |P_k| + max_{k in B} |P_k|,

i.e. ``d(t + tau) >= d(t) - l_p tau``. With the gap ``g(t) = d(t) - s`` (``s`` = min_distance),
a step ``tau = (1 - eta) g(t) / l_p`` therefore cannot close the gap: ``g(t + tau) >= eta g(t)``.
The iteration advances by such steps and stops as soon as the gap at the next trial time has
fallen below ``eta g(0)``, returning the last accepted time, which is conservative by
construction: the pair never reached ``s`` on ``[0, t]`` and ``g(t) >= eta g(0) > 0``. Reaching
``t_max`` means no impact; exceeding ``max_iterations`` returns the current (safe) time. The
argument is robust to relative errors of the computed distance below ``eta / (1 - eta)``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from geometry._distance_kernels import _classify


@njit(cache=True)
def _accd_pair(
    X0: np.ndarray,
    dX: np.ndarray,
    kind: int,
    n_a: int,
    t_max: float,
    s: float,
    eta: float,
    max_iterations: int,
) -> tuple[float, int]:
    """Conservative time of impact in [0, t_max] and iteration count of one pair."""
    nv, dim = X0.shape
    P = np.empty((nv, dim))
    X = np.empty((nv, dim))
    for c in range(dim):
        mean = 0.0
        for k in range(nv):
            mean += dX[k, c]
        mean /= nv
        for k in range(nv):
            P[k, c] = dX[k, c] - mean
    l_a = 0.0
    l_b = 0.0
    for k in range(nv):
        speed = 0.0
        for c in range(dim):
            speed += P[k, c] * P[k, c]
        speed = math.sqrt(speed)
        if k < n_a:
            l_a = max(l_a, speed)
        else:
            l_b = max(l_b, speed)
    l_p = l_a + l_b
    gap = math.sqrt(_classify(X0, kind)[1]) - s
    if gap <= 0.0:
        return 0.0, 0
    if l_p <= 0.0:
        return t_max, 0
    g_stop = eta * gap
    t = 0.0
    t_step = (1.0 - eta) * gap / l_p
    it = 0
    while True:
        it += 1
        t_next = t + t_step
        for k in range(nv):
            for c in range(dim):
                X[k, c] = X0[k, c] + t_next * P[k, c]
        gap = math.sqrt(_classify(X, kind)[1]) - s
        if gap <= 0.0 or (t > 0.0 and gap < g_stop):
            return t, it
        t = t_next
        if t >= t_max:
            return t_max, it
        if it >= max_iterations:
            return t, it
        t_step = (1.0 - eta) * gap / l_p


@njit(cache=True, parallel=True)
def _accd(
    V: np.ndarray,
    dV: np.ndarray,
    kind: int,
    n_a: int,
    t_max: float,
    min_distance: float,
    eta: float,
    max_iterations: int,
) -> tuple[np.ndarray, np.ndarray]:
    """Times of impact (n,) and iteration counts (n,) of pairs V, dV (n, nv, dim)."""
    n = V.shape[0]
    toi = np.empty(n)
    n_iter = np.empty(n, dtype=np.int64)
    for i in prange(n):
        t, it = _accd_pair(V[i], dV[i], kind, n_a, t_max, min_distance, eta, max_iterations)
        toi[i] = t
        n_iter[i] = it
    return toi, n_iter
