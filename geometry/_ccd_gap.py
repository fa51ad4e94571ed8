"""numba kernels of :mod:`geometry._ccd_kernels`: the certified gap of a pair.

**Certified gap.** Every decision uses a lower bound ``g(t) <= d(t) - s`` of the exact gap
(``d`` the exact distance of the exact trajectory, ``s`` = min_distance), never the computed
distance itself: that is what defect 3 of issue 44 missed (a point starting 1.3e-17 m above a
segment was stepped through it because the computed distance of a configuration at rounding level
is noise). Positions are taken relative to vertex 0, ``Y_k(t) = (X0_k - X0_0) + t (dX_k - dX_0)``
(the distance is translation invariant), so rounding scales with the pair's extent ``S(t) =
max_k (|D_k| + t |Q_k|) >= max_k |Y_k(t)|`` (``D_k``, ``Q_k`` the two differences), not with the
distance from the origin. :func:`_certified_gap` bounds

- the rounding of ``Y`` itself: ``3 u (|D_k| + t |Q_k|)`` per vertex (``u = 2^-53``), counted
  twice (one vertex per side);
- the rounding of the distance formulas: ``K u (S + d)`` for the point-point and point-segment
  forms (well conditioned); ``K u kappa (S + d)`` for the point-plane and line-line forms, with
  ``kappa = |u||v| / |u x v|`` the conditioning of the normal;
- a wrong closest-feature choice: where the unconstrained minimiser (barycentric coordinates,
  line parameters) is not certainly outside the domain (margin ``K u kappa^2 (1 + |r|/l_min)``),
  the plane/line distance is used, which is never above the pair's distance, or the boundary
  distance less a geometric slack (the triangle's inradius, which bounds how far a point of the
  triangle is from its boundary; ``|a^ -+ b^| min(|a|, |b|)`` for edges, which bounds how much
  farther the boundary is than an interior closest pair of near-parallel edges), whichever is
  larger.

``K = 32`` is a choice (the formulas need about ``dim + 4``); a pair whose certified gap at
``t = 0`` is not positive reports 0: "at or below the rounding of the contact test".
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from geometry._distance_kernels import KIND_PE, KIND_PT, PARALLEL_SIN2, _cross, _dot

#: unit roundoff of float64
U = 2.0**-53
#: safety factor on the first-order rounding bounds (the formulas need about dim + 4)
K_ROUND = 32.0


@njit(cache=True)
def _norm(x: np.ndarray) -> float:
    s = 0.0
    for c in range(x.shape[0]):
        s += x[c] * x[c]
    return math.sqrt(s)


@njit(cache=True, inline="always")
def _pe_closest(Y: np.ndarray, ip: int, i0: int, i1: int) -> tuple[float, float]:
    """Segment parameter lam in [0, 1] of the point of Y[i0]-Y[i1] closest to Y[ip], and the
    computed distance."""
    dim = Y.shape[1]
    a = 0.0
    b = 0.0
    for c in range(dim):
        e = Y[i1, c] - Y[i0, c]
        a += (Y[ip, c] - Y[i0, c]) * e
        b += e * e
    lam = 0.0
    if b > 0.0 and a > 0.0:
        lam = 1.0 if a >= b else a / b
    D = 0.0
    for c in range(dim):
        w = Y[ip, c] - (Y[i0, c] + lam * (Y[i1, c] - Y[i0, c]))
        D += w * w
    return lam, math.sqrt(D)


@njit(cache=True, inline="always")
def _pe_direction(Y: np.ndarray, ip: int, i0: int, i1: int, lam: float, sign: float, n: np.ndarray):
    """n = sign (closest point on segment i0-i1 - Y[ip]); for an interior closest point made
    orthogonal to the segment to rounding (one Gram-Schmidt pass): the difference itself is only
    accurate to ``u S / d`` in direction, which would make motion along the segment look like an
    approach at tiny gaps."""
    dim = Y.shape[1]
    for c in range(dim):
        n[c] = sign * (Y[i0, c] + lam * (Y[i1, c] - Y[i0, c]) - Y[ip, c])
    if 0.0 < lam < 1.0:
        ne = 0.0
        ee = 0.0
        for c in range(dim):
            e = Y[i1, c] - Y[i0, c]
            ne += n[c] * e
            ee += e * e
        for c in range(dim):
            n[c] -= ne / ee * (Y[i1, c] - Y[i0, c])


@njit(cache=True)
def _vec3(Y: np.ndarray, i: int, j: int) -> tuple[float, float, float]:
    return Y[i, 0] - Y[j, 0], Y[i, 1] - Y[j, 1], Y[i, 2] - Y[j, 2]


@njit(cache=True, inline="always")
def _certified_gap(Y: np.ndarray, kind: int, S: float, n: np.ndarray) -> float:
    """Lower bound of the exact distance of the configuration Y (nv, dim) (positions exact), and
    two candidate separating directions ``n`` (2, dim), not normalised, zero rows when undefined:
    row 0 from side A's closest point to side B's, row 1 the feature normal (the segment's in 2D,
    the face's, the edges' common one) oriented from A to B, which stays accurate at tiny gaps.
    S: max_k |Y_k| in m."""
    KU = K_ROUND * U
    n[:] = 0.0
    if kind == KIND_PE:
        lam, d = _pe_closest(Y, 0, 1, 2)
        _pe_direction(Y, 0, 1, 2, lam, 1.0, n[0])
        if Y.shape[1] == 2:  # the segment's normal, towards the segment
            ex, ey = Y[2, 0] - Y[1, 0], Y[2, 1] - Y[1, 1]
            side = ex * (Y[0, 1] - Y[1, 1]) - ey * (Y[0, 0] - Y[1, 0])
            sign = -1.0 if side > 0.0 else 1.0
            n[1, 0] = -sign * ey
            n[1, 1] = sign * ex
        return d - KU * (S + d)
    if kind == KIND_PT:
        # boundary: the closest of the three edges
        bd = np.inf
        for k in range(3):
            i0, i1 = 1 + k, 1 + (k + 1) % 3
            lam, d = _pe_closest(Y, 0, i0, i1)
            if d < bd:
                bd = d
                _pe_direction(Y, 0, i0, i1, lam, 1.0, n[0])
        lo = bd - KU * (S + bd)
        u = _vec3(Y, 2, 1)
        v = _vec3(Y, 3, 1)
        w = _vec3(Y, 3, 2)
        r = _vec3(Y, 0, 1)
        nn = _cross(u, v)
        m = _dot(nn, nn)
        lu, lv, lw = math.sqrt(_dot(u, u)), math.sqrt(_dot(v, v)), math.sqrt(_dot(w, w))
        perimeter = lu + lv + lw
        inradius = math.sqrt(m) / perimeter if perimeter > 0.0 else 0.0
        slack_lo = bd - KU * (S + bd) - inradius * (1.0 + KU)
        if not (m > PARALLEL_SIN2 * lu * lu * lv * lv):
            return slack_lo  # degenerate triangle: within its inradius of its edges
        sm = math.sqrt(m)
        kappa = lu * lv / sm
        b1 = _dot(_cross(r, v), nn) / m
        b2 = _dot(_cross(u, r), nn) / m
        lr = math.sqrt(_dot(r, r))
        eb = KU * kappa * kappa * (1.0 + lr / max(min(lu, lv, lw), 1e-300))
        rn = _dot(r, nn)
        sign = -1.0 if rn > 0.0 else 1.0  # the face normal, from the point towards the plane
        for c in range(3):
            n[1, c] = sign * nn[c]
        if min(b1, b2, 1.0 - b1 - b2) < -eb:
            return lo  # projection certainly outside: the boundary distance is the distance
        pd = abs(rn) / sm
        return max(pd - KU * kappa * (S + pd), slack_lo)
    # KIND_EE: boundary candidates b0, b1 vs edge a; a0, a1 vs edge b
    bd = np.inf
    for k in range(4):
        if k < 2:
            ip, i0, i1, sign = 2 + k, 0, 1, -1.0  # n from A (segment) to B (point)
        else:
            ip, i0, i1, sign = k - 2, 2, 3, 1.0
        lam, d = _pe_closest(Y, ip, i0, i1)
        if d < bd:
            bd = d
            _pe_direction(Y, ip, i0, i1, lam, sign, n[0])
    lo = bd - KU * (S + bd)
    a = _vec3(Y, 1, 0)
    b = _vec3(Y, 3, 2)
    r = _vec3(Y, 2, 0)
    la, lb = math.sqrt(_dot(a, a)), math.sqrt(_dot(b, b))
    # near-parallel slack: |a^ -+ b^| min(|a|, |b|) bounds boundary minus interior distance
    slack = 0.0
    if la > 0.0 and lb > 0.0:
        dm = 0.0
        dp = 0.0
        for c in range(3):
            dm += (a[c] / la - b[c] / lb) ** 2
            dp += (a[c] / la + b[c] / lb) ** 2
        slack = (math.sqrt(min(dm, dp)) + KU) * min(la, lb)
    slack_lo = lo - slack
    nn = _cross(a, b)
    m = _dot(nn, nn)
    if not (m > PARALLEL_SIN2 * la * la * lb * lb):
        return slack_lo
    sm = math.sqrt(m)
    kappa = la * lb / sm
    s_par = _dot(_cross(r, b), nn) / m
    t_par = _dot(_cross(r, a), nn) / m
    lr = math.sqrt(_dot(r, r))
    es = KU * kappa * kappa * (1.0 + lr / min(la, lb))
    rn = _dot(r, nn)
    sign = 1.0 if rn > 0.0 else -1.0  # the common normal, from edge a towards edge b
    for c in range(3):
        n[1, c] = sign * nn[c]
    if s_par < -es or s_par > 1.0 + es or t_par < -es or t_par > 1.0 + es:
        return lo  # unconstrained minimiser certainly outside: boundary distance is exact
    ld = abs(rn) / sm
    return max(ld - KU * kappa * (S + ld), slack_lo)
