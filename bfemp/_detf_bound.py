"""Largest step keeping det F > 0 along a line (paper section 5, line-search filtering).

Deformation gradients of FEM cells and MPM particles are affine in the unknowns, so along a
search direction they are ``F(alpha) = F + alpha D`` (both ``(S, d, d)``, dimensionless) and

    p(alpha) = det(F + alpha D) = c0 + c1 alpha + c2 alpha^2 + c3 alpha^3

with c0 = det F, c1 = tr(adj(F) D), c2 = tr(adj(D) F) (3D) or det D (2D), c3 = det D (3D).
The critical step is the smallest positive real root of p; the caller starts its line search at
0.9 of it.

Robust root location (one numba kernel, per point):

1. Scale.  F and D are multiplied by powers of two that bring their largest entries into
   [0.5, 1) (exact), and the step variable is rescaled accordingly, so the coefficients are O(1)
   and never overflow.
2. Certified lower bound.  Each coefficient is computed by the permutation expansion of the
   determinant; the same expansion with absolute values (the permanent of |F| + alpha |D|) bounds
   the rounding error of the coefficients and of Horner evaluation.  The kernel works with
   ``g(alpha) = sum_i (c_i - K eps |c|_i) alpha^i / c0`` (in the scaled step), a polynomial
   below p / c0 on alpha >= 0 by more than every rounding error, so ``g(alpha) > 0`` evaluated
   in floating point proves ``det(F + alpha D) > 0`` in exact arithmetic.
3. Monotone intervals.  The critical points of g (roots of the quadratic g', computed with the
   cancellation-free formula) split [0, alpha_max] into intervals where g is monotone.  The first
   interval whose right end has g <= 0 holds the first root; earlier intervals have g > 0 at both
   ends, hence throughout.
4. Safeguarded Newton.  Newton steps kept inside the bracket (bisection otherwise) shrink the
   bracket to a relative width of 1e-13; the feasible end (g > 0) is returned.

So the result is a certified lower bound of the first root.  For a simple, well-conditioned root
it is within about 1e-13 (relative); otherwise it sits below the root by the floating-point
uncertainty of the root: about K eps perm(|F|) / det F (relative) for a nearly singular F, and
(K eps)^(1/m) for an m-fold root (D = -F gives (1 - alpha)^d).  Points whose det F is positive
but not distinguishable from zero get 0.0 (no step can be certified).

Contract for the caller: ``det(F_s + t D_s) > 0`` for every point and every ``0 <= t < result``
(in particular at 0.9 * result); no root is missed.
"""

from __future__ import annotations

import logging
import math

import numpy as np
from numba import njit, prange

__all__ = ["first_det_root", "max_step_det_positive"]

logger = logging.getLogger(__name__)

# Error-bound factor: rounding errors of the permutation expansion (at most 18 monomials of
# 3 factors per coefficient), of the normalisation and of Horner's rule are all below ~30 eps
# times the absolute-value polynomial; 64 leaves a margin.
_K_TOL = 64.0 * np.finfo(np.float64).eps
_RTOL = 1e-13
_MAX_ITER = 200
_BAD_INPUT = -2.0  # sentinel: non-finite entries in F or D
_NOT_POSITIVE = -1.0  # sentinel: det F <= 0

# Permutations of (0, 1, 2) and of (0, 1) with their signs (Leibniz formula).
_PERM3 = np.array([[0, 1, 2], [1, 2, 0], [2, 0, 1], [0, 2, 1], [2, 1, 0], [1, 0, 2]])
_SIGN3 = np.array([1.0, 1.0, 1.0, -1.0, -1.0, -1.0])
_PERM2 = np.array([[0, 1], [1, 0]])
_SIGN2 = np.array([1.0, -1.0])


@njit(cache=True)
def _exponent(x: float) -> int:
    """The integer e with 2^(e-1) <= x < 2^e (x > 0 finite)."""
    return math.frexp(x)[1]


@njit(cache=True)
def _coefficients(F: np.ndarray, D: np.ndarray, s: int, ef: int, ed: int) -> tuple:
    """Coefficients of det(A + b B), A = F[s] 2^-ef, B = D[s] 2^-ed, and of its absolute bound.

    Each permutation term prod_i (x_i + b y_i) expands into elementary symmetric sums of the
    x's and y's; the signed sum gives the determinant, the sum of absolute values the permanent
    of |A| + b |B|, which bounds the rounding error of every coefficient.  The power-of-two
    scalings are exact; each is applied as two factors so that neither factor over/underflows.
    """
    fi = math.ldexp(1.0, -(ef // 2))
    fi2 = math.ldexp(1.0, ef // 2 - ef)
    di = math.ldexp(1.0, -(ed // 2))
    di2 = math.ldexp(1.0, ed // 2 - ed)
    d = F.shape[1]
    c0 = c1 = c2 = c3 = 0.0
    a0 = a1 = a2 = a3 = 0.0
    if d == 2:
        for p in range(2):
            x1 = F[s, 0, _PERM2[p, 0]] * fi * fi2
            x2 = F[s, 1, _PERM2[p, 1]] * fi * fi2
            y1 = D[s, 0, _PERM2[p, 0]] * di * di2
            y2 = D[s, 1, _PERM2[p, 1]] * di * di2
            sg = _SIGN2[p]
            c0 += sg * (x1 * x2)
            c1 += sg * (x1 * y2 + y1 * x2)
            c2 += sg * (y1 * y2)
            x1, x2, y1, y2 = abs(x1), abs(x2), abs(y1), abs(y2)
            a0 += x1 * x2
            a1 += x1 * y2 + y1 * x2
            a2 += y1 * y2
        return c0, c1, c2, c3, a0, a1, a2, a3
    for p in range(6):
        x1 = F[s, 0, _PERM3[p, 0]] * fi * fi2
        x2 = F[s, 1, _PERM3[p, 1]] * fi * fi2
        x3 = F[s, 2, _PERM3[p, 2]] * fi * fi2
        y1 = D[s, 0, _PERM3[p, 0]] * di * di2
        y2 = D[s, 1, _PERM3[p, 1]] * di * di2
        y3 = D[s, 2, _PERM3[p, 2]] * di * di2
        sg = _SIGN3[p]
        c0 += sg * (x1 * x2 * x3)
        c1 += sg * (y1 * x2 * x3 + x1 * y2 * x3 + x1 * x2 * y3)
        c2 += sg * (x1 * y2 * y3 + y1 * x2 * y3 + y1 * y2 * x3)
        c3 += sg * (y1 * y2 * y3)
        x1, x2, x3, y1, y2, y3 = abs(x1), abs(x2), abs(x3), abs(y1), abs(y2), abs(y3)
        a0 += x1 * x2 * x3
        a1 += y1 * x2 * x3 + x1 * y2 * x3 + x1 * x2 * y3
        a2 += x1 * y2 * y3 + y1 * x2 * y3 + y1 * y2 * x3
        a3 += y1 * y2 * y3
    return c0, c1, c2, c3, a0, a1, a2, a3


@njit(cache=True)
def _horner(g0: float, g1: float, g2: float, g3: float, t: float) -> tuple:
    """g(t) and g'(t) of the cubic g0 + g1 t + g2 t^2 + g3 t^3 (never NaN for finite t >= 0)."""
    v = g3
    dv = 0.0
    v, dv = g2 + t * v, v + t * dv
    v, dv = g1 + t * v, v + t * dv
    v, dv = g0 + t * v, v + t * dv
    return v, dv


@njit(cache=True)
def _value_at_end(g0: float, g1: float, g2: float, g3: float, t: float) -> float:
    """g(t); for t = +inf the sign of the leading nonzero coefficient (g0 if constant)."""
    if t < np.inf:
        return _horner(g0, g1, g2, g3, t)[0]
    if g3 != 0.0:
        return g3
    if g2 != 0.0:
        return g2
    if g1 != 0.0:
        return g1
    return g0


@njit(cache=True)
def _split(lo: float, hi: float) -> float:
    """Bisection point: geometric mean across orders of magnitude, else the midpoint."""
    if lo > 0.0 and hi > 4.0 * lo:
        return math.sqrt(lo) * math.sqrt(hi)
    return 0.5 * (lo + hi)


@njit(cache=True)
def _solve_bracket(g0: float, g1: float, g2: float, g3: float, lo: float, hi: float) -> float:
    """Largest certified-feasible point below the root of g in [lo, hi].

    Requires g(lo) > 0 >= g(hi) and g monotone (decreasing) on [lo, hi]; hi may be +inf.
    Returns a point x with g(x) > 0 and root - x <= 1e-13 root (fewer digits only if the
    iteration budget runs out, which keeps the result feasible).
    """
    if hi == np.inf:
        # Expand geometrically until the (eventually dominant, negative) leading term wins.
        t = max(2.0 * lo, 1.0)
        for _ in range(2200):
            if _horner(g0, g1, g2, g3, t)[0] <= 0.0:
                break
            lo = t
            t *= 2.0
        else:
            return lo
        hi = t
    if lo == 0.0:
        # Cauchy's bound on the reversed polynomial: every root has t >= g0 / (g0 + max |g_i|).
        t = 0.5 * g0 / (g0 + max(abs(g1), abs(g2), abs(g3)))
        if t < hi and _horner(g0, g1, g2, g3, t)[0] > 0.0:
            lo = t
    x = _split(lo, hi)
    width_1 = width_2 = hi - lo  # bracket widths one and two iterations ago
    for _ in range(_MAX_ITER):
        gx, dgx = _horner(g0, g1, g2, g3, x)
        if gx > 0.0:
            lo = x
        else:
            hi = x
        width = hi - lo
        if width <= _RTOL * hi:
            break
        xn = x - gx / dgx if dgx < 0.0 else np.nan
        if not (lo < xn < hi) or width > 0.5 * width_2 or hi > 4.0 * lo:
            # Newton left the bracket, or the bracket did not halve in two steps, or it spans
            # orders of magnitude (Newton from far out gains only a constant factor): bisect.
            xn = _split(lo, hi)
        elif abs(xn - x) <= 0.25 * _RTOL * hi:
            # Newton has converged to within the tolerance: probe both sides to close the bracket.
            w = 0.25 * _RTOL * hi
            for probe in (xn - w, xn + w):
                if lo < probe < hi:
                    if _horner(g0, g1, g2, g3, probe)[0] > 0.0:
                        lo = probe
                    else:
                        hi = probe
            if hi - lo <= _RTOL * hi:
                break
            xn = 0.5 * (lo + hi)
        width_2 = width_1
        width_1 = hi - lo
        x = xn
    return lo


@njit(cache=True)
def _first_root_cubic(g0: float, g1: float, g2: float, g3: float, t_max: float) -> float:
    """Certified lower bound of the first root of g in (0, t_max], t_max if none (g0 > 0)."""
    # Critical points: roots of g' = 3 g3 t^2 + 2 g2 t + g1, computed without cancellation
    # (q = -(B + sign(B) sqrt(B^2 - 4AC)) / 2, roots q/A and C/q).
    A = 3.0 * g3
    B = 2.0 * g2
    C = g1
    r1 = np.nan
    r2 = np.nan
    if A == 0.0:
        if B != 0.0:
            r1 = -C / B
    else:
        disc = B * B - 4.0 * A * C
        if disc >= 0.0:
            q = -0.5 * (B + math.copysign(math.sqrt(disc), B))
            if q != 0.0:
                r1 = q / A
                r2 = C / q
            else:
                r1 = 0.0
    if r2 < r1:
        r1, r2 = r2, r1
    lo = 0.0
    for t in (r1, r2, t_max):
        if not (lo < t <= t_max):  # NaN and points outside (lo, t_max] are skipped
            continue
        if _value_at_end(g0, g1, g2, g3, t) <= 0.0:
            return _solve_bracket(g0, g1, g2, g3, lo, t)
        lo = t
    return t_max


@njit(cache=True, parallel=True)
def _first_det_root_kernel(F: np.ndarray, D: np.ndarray, alpha_max: float, out: np.ndarray) -> None:
    d = F.shape[1]
    for s in prange(F.shape[0]):  # points are independent: the result is the serial one
        f_max = 0.0
        d_max = 0.0
        finite = True
        for i in range(d):
            for j in range(d):
                f = abs(F[s, i, j])
                g = abs(D[s, i, j])
                finite = finite and f < np.inf and g < np.inf  # False for inf and NaN
                f_max = max(f_max, f)
                d_max = max(d_max, g)
        if not finite:
            out[s] = _BAD_INPUT
            continue
        if f_max == 0.0:
            out[s] = _NOT_POSITIVE
            continue
        ef = _exponent(f_max)
        ed = _exponent(d_max) if d_max > 0.0 else 0
        # det(F + alpha D) = 2^(d ef) det(A + b B) with b = alpha 2^(ed - ef) (exact scalings).
        c0, c1, c2, c3, a0, a1, a2, a3 = _coefficients(F, D, s, ef, ed)
        if not c0 > 0.0:
            out[s] = _NOT_POSITIVE
            continue
        if d_max == 0.0:
            out[s] = alpha_max
            continue
        inv = 1.0 / c0
        g0 = (c0 - _K_TOL * a0) * inv
        if not g0 > 0.0:
            out[s] = 0.0  # det F > 0 but within rounding of 0: no step is certified
            continue
        g1 = (c1 - _K_TOL * a1) * inv
        g2 = (c2 - _K_TOL * a2) * inv
        g3 = (c3 - _K_TOL * a3) * inv
        b_max = math.ldexp(alpha_max, ed - ef)  # may be +inf: handled by the root finder
        b = _first_root_cubic(g0, g1, g2, g3, b_max)
        out[s] = alpha_max if b >= b_max else min(math.ldexp(b, ef - ed), alpha_max)


def first_det_root(F: np.ndarray, D: np.ndarray, alpha_max: float = 1.0) -> np.ndarray:
    """Per point, the first step at which det(F + alpha D) reaches 0, capped at alpha_max.

    Args:
        F: deformation gradients (S, d, d), d = 2 or 3, dimensionless, det F > 0 required.
        D: their derivative along the step (S, d, d), dimensionless per unit step.
        alpha_max: largest step of interest (> 0, dimensionless).

    Returns:
        alpha (S,): certified lower bound of the smallest positive root of det(F_s + a D_s),
        or exactly ``alpha_max`` where there is no root in (0, alpha_max]. det stays > 0 on
        [0, alpha_s). 0.0 where det F_s is positive but indistinguishable from zero.

    Raises:
        ValueError: bad shapes, alpha_max not finite and > 0, non-finite entries, det F <= 0
            (the message lists the offending points).
    """
    F = np.ascontiguousarray(F, dtype=np.float64)
    D = np.ascontiguousarray(D, dtype=np.float64)
    if F.ndim != 3 or F.shape[1] != F.shape[2] or F.shape[1] not in (2, 3):
        raise ValueError(f"F must have shape (S, d, d) with d in (2, 3), got {F.shape}")
    if D.shape != F.shape:
        raise ValueError(f"D must have the shape of F {F.shape}, got {D.shape}")
    if not (math.isfinite(alpha_max) and alpha_max > 0.0):
        raise ValueError(f"alpha_max must be finite and > 0, got {alpha_max}")
    out = np.empty(F.shape[0])
    _first_det_root_kernel(F, D, float(alpha_max), out)
    if F.shape[0] and out.min() < 0.0:
        bad = np.flatnonzero(out == _BAD_INPUT)
        if bad.size:
            raise ValueError(f"F or D has non-finite entries at points {bad[:10].tolist()}")
        bad = np.flatnonzero(out == _NOT_POSITIVE)
        raise ValueError(f"det F <= 0 at points {bad[:10].tolist()} (det F > 0 is required)")
    n_zero = np.count_nonzero(out == 0.0)
    if n_zero:
        logger.warning("det F indistinguishable from 0 at %d points: step bound 0", n_zero)
    return out


def max_step_det_positive(F: np.ndarray, D: np.ndarray, *, alpha_max: float = 1.0) -> float:
    """Largest step t in [0, alpha_max] such that det(F_s + a D_s) > 0 for all s and a < t.

    Arguments as in :func:`first_det_root`. Returns min(alpha_max, first positive root over all
    points), a certified lower bound; alpha_max when S = 0 or no point reaches det = 0. The
    caller starts its line search at 0.9 times this value.
    """
    roots = first_det_root(F, D, alpha_max)
    return float(roots.min()) if roots.size else float(alpha_max)
