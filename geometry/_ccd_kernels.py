"""numba kernels of :mod:`geometry.ccd`: additive continuous collision detection (ACCD) with
certified distance bounds and a separating-plane step.

The line search's first step is 0.9 x this conservative time of impact (BFEMP sec. 5, "the
critical value for 0 distance is computed via continuous collision detection"; the paper cites
CCD without fixing the method, so ACCD, the certified bounds and the plane step are this
module's choices).

Private: array-in / array-out, no validation. Additive CCD (Li, Kaufman, Jiang 2021,
"Codimensional Incremental Potential Contact", Alg. 1) for one pair with vertices
``X0 (nv, dim)`` moving linearly by ``dX (nv, dim)``: ``x_k(t) = X0_k + t dX_k``. Side A is the
first ``n_a`` vertices (the point, or edge a), side B the rest.

**Certified gap**: :mod:`geometry._ccd_gap` (:func:`_certified_gap`, a lower bound
``g(t) <= d(t) - s`` of the exact gap, used by every decision below).

**Steps.** From an accepted time ``t`` with certified gap ``g(t) > 0`` the next time is the
larger of

- the ACCD step ``(1 - eta) g(t) / l_p`` with ``l_p = max_A |P_k| + max_B |P_k|``, ``P_k = dX_k
  - mean(dX)``, which bounds ``|d'|`` (Li et al. 2021, Alg. 1), so ``d - s >= eta g(t) > 0`` on
  the step;
- the separating-plane step (a choice of this module; the ACCD paper only has the first): with
  ``n`` the unit direction between the closest points at ``t``, ``d(t') >= min_B n.x_b(t') -
  max_A n.x_a(t') = min_{a, b} (alpha_ab + beta_ab t')``, a concave, piecewise-linear function of
  ``t'``, so the step may go as far as every ``alpha_ab + beta_ab t'`` (less its rounding bound)
  stays at or above ``s + g_stop``. Motion parallel to the plane (a point sliding along a segment
  or a face, parallel edges) has ``beta = 0`` and finishes in one step: this bounds the cost of
  parallel near-contact motion (defect 4 of issue 44: 1e6 steps, 43 ms, toi 9e-4 before).

- for a 2D point-edge pair, the line step (a choice of this module): the orientation ``o(t) =
  (e_0 - p) x (e_1 - p)`` is a quadratic in t and ``|o| / |e_1 - e_0|`` the distance from the
  segment's line, never above the distance from the segment; with a linear upper bound of the
  length the condition "line distance >= s + g_stop" is a quadratic inequality, certified with
  bounds of its rounding, and the step goes to (just before) its first root after t
  (:func:`_line_coefficients`, :func:`_line_limit`). This is what bounds the cost of *turning*
  near-contact motion in 2D, where the separating direction rotates and neither of the first two
  steps is long (issue 44: an edge turning about the foot of a point 1e-9 above it took the 1e6
  iteration cap, ~200 ms, and returned toi 9e-4 for a pair that never touches; now one step,
  toi 1). After a line step that ended at its root, the next line step is only taken when it is
  at least as long (else re-finding the same root creeps up to it in ever shorter steps).

The plane step is skipped after it fails to beat the ACCD step (turning motion), for 2, 4, ..
64 iterations, so that motion it cannot help pays little for it. The iteration stops, returning
the last accepted time, when the next time is not certified to
keep ``g >= g_stop = eta g(0)`` (by the plane, the Lipschitz bound or the distance there);
``t_max`` means no impact; ``max_iterations`` returns the current (safe) time. Rounding of the
times themselves is checked (the step actually taken, ``t_next - t``, must fit the bound).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from geometry._ccd_gap import K_ROUND, U, _certified_gap, _norm
from geometry._distance_kernels import KIND_PE


@njit(cache=True, inline="always")
def _gap_at(
    t: float,
    D: np.ndarray,
    Q: np.ndarray,
    nD: np.ndarray,
    nQ: np.ndarray,
    kind: int,
    s: float,
    Y: np.ndarray,
    n: np.ndarray,
) -> float:
    """Certified gap (lower bound of d - s) at time t, and the closest-point direction in n."""
    nv, dim = D.shape
    S = 0.0  # bound of max_k |Y_k|: |D_k| + t |Q_k|
    for k in range(nv):
        for c in range(dim):
            Y[k, c] = D[k, c] + t * Q[k, c]
        S = max(S, nD[k] + t * nQ[k])
    S *= 1.0 + 4.0 * U
    pos_err = 3.0 * U * S
    return _certified_gap(Y, kind, S, n) - 2.0 * pos_err * (1.0 + 4.0 * U) - s


@njit(cache=True, inline="always")
def _plane_limit(
    t: float,
    n: np.ndarray,
    D: np.ndarray,
    Q: np.ndarray,
    nD: np.ndarray,
    nQ: np.ndarray,
    n_a: int,
    level: float,
) -> float:
    """Latest time t' >= t such that the separation along the direction n (dim,) certifies
    d >= level on [t, t']; t when it does not hold at t, inf when it holds for all later times."""
    nv, dim = D.shape
    ln = _norm(n)
    if not (ln > 0.0) or not np.isfinite(ln):
        return t
    KU = K_ROUND * U
    c_level = level * (1.0 + 8.0 * U)
    t_lim = np.inf
    for ia in range(n_a):
        for ib in range(n_a, nv):
            alpha = 0.0
            beta = 0.0
            for c in range(dim):
                nc = n[c] / ln
                alpha += nc * (D[ib, c] - D[ia, c])
                beta += nc * (Q[ib, c] - Q[ia, c])
            a_lo = alpha - KU * (nD[ia] + nD[ib]) - 4.0 * U * abs(alpha)
            b_lo = beta - KU * (nQ[ia] + nQ[ib]) - 4.0 * U * abs(beta)
            if a_lo + b_lo * t < c_level * (1.0 + 4.0 * U):
                return t
            if b_lo < 0.0:
                t_lim = min(t_lim, (a_lo - c_level) / (-b_lo) * (1.0 - 8.0 * U))
    return max(t, t_lim)


@njit(cache=True, inline="always")
def _line_coefficients(
    D: np.ndarray, Q: np.ndarray, nD: np.ndarray, nQ: np.ndarray
) -> tuple[float, float, float, float, float, float, float]:
    """Coefficients of the certified line-separation polynomials of a 2D point-edge pair (a
    choice of this module, beside the ACCD and plane steps).

    With the point as vertex 0, ``e_i(t) = D_i + t Q_i`` (i = 1, 2) the segment's ends relative
    to it, the orientation ``o(t) = e_1(t) x e_2(t) = c0 + c1 t + c2 t^2`` is a quadratic (the
    cross product of two linear vectors) and ``|o(t)| / |e_2(t) - e_1(t)|`` is the distance of
    the point from the segment's *line*, never above its distance from the segment. With
    ``|e_2(t') - e_1(t')| <= Lc + t' L1`` (:func:`_line_length`), ``d(t') >= level`` wherever,
    for sigma = +1 or -1,

        f_sigma(t') = sigma o(t') - E(t') - level (Lc + t' L1) > 0,

    ``E(t) = e0 + e1 t + e2 t^2 = 2 K u (|D_1| + t |Q_1|)(|D_2| + t |Q_2|)`` the bound of the
    rounding of ``o``: of the differences D, Q (``2 u B_1 B_2``) and of the coefficients (``3 u
    B_1 B_2``, as ``|c0| <= |D_1||D_2|`` etc.), with twice the module's safety factor so that it
    also covers the rounding of f's own coefficients. Returns ``(c2, c1, c0, e2, e1, e0, L1)``,
    in m^2 (L1 in m)."""
    D1x, D1y, D2x, D2y = D[1, 0], D[1, 1], D[2, 0], D[2, 1]
    Q1x, Q1y, Q2x, Q2y = Q[1, 0], Q[1, 1], Q[2, 0], Q[2, 1]
    c0 = D1x * D2y - D1y * D2x
    c1 = (D1x * Q2y - D1y * Q2x) + (Q1x * D2y - Q1y * D2x)
    c2 = Q1x * Q2y - Q1y * Q2x
    KU = 2.0 * K_ROUND * U
    e0 = KU * nD[1] * nD[2]
    e1 = KU * (nD[1] * nQ[2] + nQ[1] * nD[2])
    e2 = KU * nQ[1] * nQ[2]
    lqx, lqy = Q2x - Q1x, Q2y - Q1y
    L1 = math.sqrt(lqx * lqx + lqy * lqy) * (1.0 + 8.0 * U) + 4.0 * U * (nQ[1] + nQ[2])
    return c2, c1, c0, e2, e1, e0, L1


@njit(cache=True, inline="always")
def _line_length(t: float, Y: np.ndarray, nD: np.ndarray, nQ: np.ndarray, L1: float) -> float:
    """Lc such that the exact segment length at t' >= t is at most ``Lc + t' L1``: the length
    at t, ``|fl(Y_2 - Y_1)|`` with Y the rounded positions at t (each within ``3 u B_k`` of
    ``D_k + t Q_k``, which is within ``u B_k`` of the exact one, ``B_k = |D_k| + t |Q_k|``), plus
    ``(t' - t) L1``."""
    lx, ly = Y[2, 0] - Y[1, 0], Y[2, 1] - Y[1, 1]
    B = nD[1] + nD[2] + t * (nQ[1] + nQ[2])
    Lt = math.sqrt(lx * lx + ly * ly) * (1.0 + 8.0 * U) + 8.0 * U * B
    return Lt - t * L1 + 4.0 * U * (Lt + t * L1)


@njit(cache=True, inline="always")
def _quad_positive(A: float, B: float, C: float, t: float) -> bool:
    """Whether A t^2 + B t + C (float coefficients, exact evaluation) is certainly > 0 at t:
    the computed value beats the rounding bound of Horner's rule."""
    v = (A * t + B) * t + C
    return v > 8.0 * U * ((abs(A) * t + abs(B)) * t + abs(C))


@njit(cache=True, inline="always")
def _line_limit(t: float, t_max: float, coef: tuple, level: float, Lc: float) -> float:
    """Latest time t' in [t, t_max] such that one of the quadratics of
    :func:`_line_coefficients` is certified positive on all of [t, t'] (so the point stays at
    least ``level`` from the segment's line, hence from the segment); t when neither is positive
    at t.

    The candidate is the first root after t (stable quadratic formula) pulled back by 1e-6 of the
    step; it is accepted only when the quadratic is certified positive there and, if convex,
    at its vertex when that lies inside (a quadratic positive at both ends of an interval is
    positive on it unless its vertex dips in between); else the step is quartered, up to 4
    times."""
    best = t
    lv = level * (1.0 + 8.0 * U)
    c2, c1, c0, e2, e1, e0, L1 = coef
    for row in range(2):
        sigma = 1.0 - 2.0 * row
        A = sigma * c2 - e2
        # lv (Lc + t' L1) > 0, but Lc alone may be negative and large (a fast-growing segment
        # late in the step): its rounding is bounded apart, relative to |Lc|
        B = (sigma * c1 - e1) - lv * L1
        C = (sigma * c0 - e0) - lv * (Lc + 4.0 * U * abs(Lc))
        if not _quad_positive(A, B, C, t):
            continue
        # first root after t of A x^2 + B x + C (none: t_max)
        end = t_max
        if A == 0.0:
            if B < 0.0:
                end = min(end, -C / B)
        else:
            disc = B * B - 4.0 * A * C
            if disc >= 0.0:
                sq = math.sqrt(disc)
                q = -0.5 * (B + sq) if B >= 0.0 else -0.5 * (B - sq)
                for r in (q / A, C / q if q != 0.0 else -np.inf):
                    if r > t:
                        end = min(end, r)
        if not (end > best):
            continue
        step = end - t
        if end < t_max:
            step *= 1.0 - 1e-6
        tv = -B / (2.0 * A) if A > 0.0 else -np.inf
        for _ in range(5):
            t_next = t + step
            if not (t_next > best):
                break
            if _quad_positive(A, B, C, t_next) and (
                not (t < tv < t_next) or _quad_positive(A, B, C, tv)
            ):
                best = min(t_next, t_max)
                break
            step *= 0.25
    return best


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
    D = np.empty((nv, dim))
    Q = np.empty((nv, dim))
    nD = np.empty(nv)
    nQ = np.empty(nv)
    Y = np.empty((nv, dim))
    n = np.zeros((2, dim))
    for k in range(nv):
        for c in range(dim):
            D[k, c] = X0[k, c] - X0[0, c]
            Q[k, c] = dX[k, c] - dX[0, c]
        nD[k] = _norm(D[k]) * (1.0 + 4.0 * U)
        nQ[k] = _norm(Q[k]) * (1.0 + 4.0 * U)
    # Lipschitz bound of the distance (Li et al. 2021): mean-free speeds, rounded up.
    l_a = 0.0
    l_b = 0.0
    for k in range(nv):
        speed = 0.0
        for c in range(dim):
            mean = 0.0
            for j in range(nv):
                mean += dX[j, c]
            p = dX[k, c] - mean / nv
            speed += p * p
        speed = math.sqrt(speed)
        if k < n_a:
            l_a = max(l_a, speed)
        else:
            l_b = max(l_b, speed)
    l_p = (l_a + l_b) * (1.0 + 16.0 * U)
    g = _gap_at(0.0, D, Q, nD, nQ, kind, s, Y, n)
    if not (g > 0.0):
        return 0.0, 0
    if l_p <= 0.0:
        return t_max, 0
    g_stop = eta * g
    # 2D point-edge: the line-separation step (a quadratic, certified; see _line_coefficients)
    line = kind == KIND_PE and dim == 2
    coef = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    if line:
        coef = _line_coefficients(D, Q, nD, nQ)
    t = 0.0
    it = 0
    skip = 0
    wait = 1
    line_min = 0.0
    while True:
        it += 1
        t_lip = t
        if g > 0.0:
            t_lip = t + (1.0 - eta) * g / l_p
            if not (t_lip - t <= g / l_p):  # rounding of t made the step too long
                t_lip = t
        t_plane = t
        if skip == 0 or t_lip <= t:
            for row in range(n.shape[0]):  # the latest limit of the directions n (rows)
                t_plane = max(t_plane, _plane_limit(t, n[row], D, Q, nD, nQ, n_a, s + g_stop))
            if t_plane > t_lip:
                wait = 1
            else:  # the plane did not help (turning motion): try it again after 2, 4, .. 64
                wait = min(2 * wait, 64)
                skip = wait
        else:
            skip -= 1
        t_line = t
        if line:
            Lc = _line_length(t, Y, nD, nQ, coef[6])
            t_line = _line_limit(t, t_max, coef, s + g_stop, Lc)
            if t_line - t < line_min:  # its certificate is spent: no creeping up to its root
                t_line = t
        t_next = max(t_lip, t_plane, t_line)
        by_line = t_line >= t_next and t_plane < t_next
        by_plane = t_plane >= t_next or by_line
        if t_next >= t_max:
            t_next = t_max
        if not (t_next > t):
            return t, it
        g_lip = g - l_p * (t_next - t)  # Lipschitz certificate at t_next (if t_next <= t_lip)
        g_next = _gap_at(t_next, D, Q, nD, nQ, kind, s, Y, n)
        if not (by_plane or g_next >= g_stop or (t == 0.0 and g_lip > 0.0)):
            return t, it
        # a line step that ended at its quadratic's root leaves only a sliver of that root's
        # interval: the next may only be taken if it is at least as long
        line_min = t_next - t if by_line else 0.0
        t = t_next
        g = g_next
        if t >= t_max:
            return t_max, it
        if it >= max_iterations:
            return t, it


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
