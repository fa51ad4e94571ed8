"""numba kernels of :mod:`geometry.distance`: feature-pair distances in difference coordinates.

Private: array-in / array-out, no validation. Every closest-feature pair is a function of at most
three difference vectors ``y = C x``, where ``x`` stacks the feature's vertices and ``C`` is a
constant block matrix whose blocks are multiples of the identity (``_C``):

=============  =====================  ==========================================
feature        local vertices         difference vectors ``y``
=============  =====================  ==========================================
point-point    (p, q)                 w = p - q
point-line     (p, e0, e1)            r = p - e0, e = e1 - e0
point-plane    (p, t0, t1, t2)        r = p - t0, u = t1 - t0, v = t2 - t0
line-line      (a0, a1, b0, b1)       r = b0 - a0, u = a1 - a0, v = b1 - b0
=============  =====================  ==========================================

Point-point and point-line give the squared distance ``D`` in closed form,

    D_pp = w.w,        D_pl = |r - lam e|^2 with lam = r.e / e.e,

while point-plane and line-line share the signed distance ``f = r.(u x v) / |u x v|`` (``D = f^2``):
differentiating ``f`` directly avoids the cancellation of ``hess D / 2d - grad D grad D^T / 4 d^3``
as ``d -> 0`` (``f`` is affine in the point). :func:`_finish` turns the feature quantity into the
requested one by the chain rule

    d = sqrt(D):  grad d = grad D / (2 d),  hess d = hess D / (2 d) - grad D grad D^T / (4 d^3),
    D = f^2:      grad D = 2 f grad f,      hess D = 2 grad f grad f^T + 2 f hess f,
    d = |f|:      grad d = sign(f) grad f,  hess d = sign(f) hess f,

and :func:`_scatter` pulls it back to the vertex slots of the pair (``grad_x = C^T grad_y``,
``hess_x = C^T hess_y C``). Where ``d = 0`` the unsigned distance is not differentiable; the kernels
return a zero gradient and Hessian there, which is an element of its (Clarke) subdifferential.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# Feature codes (rows of _C, _NA, _NK).
FEAT_PP = 0
FEAT_PL = 1
FEAT_PLANE = 2
FEAT_LL = 3

# y_a = sum_k _C[feature, a, k] x_k (a: difference vector, k: local vertex).
_C = np.zeros((4, 3, 4))
_C[FEAT_PP, 0, :2] = (1.0, -1.0)
_C[FEAT_PL, 0, :3] = (1.0, -1.0, 0.0)
_C[FEAT_PL, 1, :3] = (0.0, -1.0, 1.0)
_C[FEAT_PLANE] = ((1.0, -1.0, 0.0, 0.0), (0.0, -1.0, 1.0, 0.0), (0.0, -1.0, 0.0, 1.0))
_C[FEAT_LL] = ((-1.0, 0.0, 1.0, 0.0), (-1.0, 1.0, 0.0, 0.0), (0.0, 0.0, -1.0, 1.0))
_NA = np.array([1, 2, 3, 3])  # number of difference vectors
_NK = np.array([2, 3, 4, 4])  # number of local vertices


@njit(cache=True)
def _differences(feat: int, X: np.ndarray, blocks: np.ndarray, y: np.ndarray) -> None:
    """y[a] = sum_k C[a, k] X[blocks[k]]; X (nv, dim) pair vertices, y (>= na, dim)."""
    dim = X.shape[1]
    for a in range(_NA[feat]):
        for c in range(dim):
            acc = 0.0
            for k in range(_NK[feat]):
                acc += _C[feat, a, k] * X[blocks[k], c]
            y[a, c] = acc


@njit(cache=True)
def _pp_squared(y: np.ndarray, gy: np.ndarray, Hy: np.ndarray, order: int) -> float:
    """D = w.w for y = (w,) (1, dim); gradient 2 w, Hessian 2 I written to gy, Hy."""
    dim = y.shape[1]
    D = 0.0
    for c in range(dim):
        D += y[0, c] * y[0, c]
        if order >= 1:
            gy[c] = 2.0 * y[0, c]
    if order >= 2:
        for i in range(dim):
            for j in range(dim):
                Hy[i, j] = 2.0 if i == j else 0.0
    return D


@njit(cache=True)
def _pl_squared(y: np.ndarray, gy: np.ndarray, Hy: np.ndarray, order: int) -> float:
    """Squared point-line distance for y = (r, e) (2, dim), with derivatives in (r, e).

    With lam = r.e / b, b = e.e, w = r - lam e and q = r - 2 lam e:
    grad = (2 w, -2 lam w); hess_rr = 2 (I - e e^T / b), hess_re = -2 e q^T / b - 2 lam I,
    hess_ee = -2 q q^T / b + 2 lam^2 I.
    """
    dim = y.shape[1]
    a = 0.0
    b = 0.0
    for c in range(dim):
        a += y[0, c] * y[1, c]
        b += y[1, c] * y[1, c]
    lam = a / b
    D = 0.0
    for c in range(dim):
        w = y[0, c] - lam * y[1, c]
        D += w * w
        if order >= 1:
            gy[c] = 2.0 * w
            gy[dim + c] = -2.0 * lam * w
    if order >= 2:
        for i in range(dim):
            ei = y[1, i]
            qi = y[0, i] - 2.0 * lam * ei
            for j in range(dim):
                ej = y[1, j]
                qj = y[0, j] - 2.0 * lam * ej
                delta = 1.0 if i == j else 0.0
                Hy[i, j] = 2.0 * (delta - ei * ej / b)
                Hy[i, dim + j] = -2.0 * ei * qj / b - 2.0 * lam * delta
                Hy[dim + j, i] = Hy[i, dim + j]
                Hy[dim + i, dim + j] = -2.0 * qi * qj / b + 2.0 * lam * lam * delta
    return D


@njit(cache=True)
def _add_skew(H: np.ndarray, i0: int, j0: int, a: np.ndarray, scale: float) -> None:
    """H[i0:i0+3, j0:j0+3] += scale [a]_x, where [a]_x b = a x b."""
    H[i0 + 0, j0 + 1] -= scale * a[2]
    H[i0 + 0, j0 + 2] += scale * a[1]
    H[i0 + 1, j0 + 0] += scale * a[2]
    H[i0 + 1, j0 + 2] -= scale * a[0]
    H[i0 + 2, j0 + 0] -= scale * a[1]
    H[i0 + 2, j0 + 1] += scale * a[0]


@njit(cache=True)
def _cross(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    """out = a x b for 3-vectors."""
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@njit(cache=True)
def _ruv_signed(y: np.ndarray, gy: np.ndarray, Hy: np.ndarray, order: int) -> float:
    """Signed distance f = s / sqrt(m), s = r.n, m = n.n, n = u x v, for y = (r, u, v) (3, 3).

    grad s = (n, v x r, r x u); grad m = (0, 2 (|v|^2 u - (u.v) v), 2 (|u|^2 v - (u.v) u));
    hess s has the skew blocks (r,u) = -[v]x, (r,v) = [u]x, (u,v) = -[r]x;
    hess m: uu = 2 (|v|^2 I - v v^T), vv = 2 (|u|^2 I - u u^T), uv = 2 (2 u v^T - v u^T - (u.v) I);
    hess f = hess s / m^1/2 - (gs gm^T + gm gs^T) / (2 m^3/2) - s hess m / (2 m^3/2)
             + 3 s gm gm^T / (4 m^5/2).
    """
    r = y[0]
    u = y[1]
    v = y[2]
    n = np.empty(3)
    _cross(u, v, n)
    m = n[0] * n[0] + n[1] * n[1] + n[2] * n[2]
    s = r[0] * n[0] + r[1] * n[1] + r[2] * n[2]
    rm = 1.0 / math.sqrt(m)
    f = s * rm
    if order < 1:
        return f
    gs = np.empty(9)
    gm = np.zeros(9)
    gs[0:3] = n
    _cross(v, r, gs[3:6])
    _cross(r, u, gs[6:9])
    uu = u[0] * u[0] + u[1] * u[1] + u[2] * u[2]
    vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
    uv = u[0] * v[0] + u[1] * v[1] + u[2] * v[2]
    for c in range(3):
        gm[3 + c] = 2.0 * (vv * u[c] - uv * v[c])
        gm[6 + c] = 2.0 * (uu * v[c] - uv * u[c])
    rm3 = rm * rm * rm
    for i in range(9):
        gy[i] = gs[i] * rm - 0.5 * s * rm3 * gm[i]
    if order < 2:
        return f
    c_m = -0.5 * s * rm3
    c_mm = 0.75 * s * rm3 * rm * rm
    for i in range(9):
        for j in range(9):
            Hy[i, j] = -0.5 * rm3 * (gs[i] * gm[j] + gm[i] * gs[j]) + c_mm * gm[i] * gm[j]
    _add_skew(Hy, 0, 3, v, -rm)
    _add_skew(Hy, 3, 0, v, rm)
    _add_skew(Hy, 0, 6, u, rm)
    _add_skew(Hy, 6, 0, u, -rm)
    _add_skew(Hy, 3, 6, r, -rm)
    _add_skew(Hy, 6, 3, r, rm)
    for i in range(3):
        for j in range(3):
            delta = 1.0 if i == j else 0.0
            Hy[3 + i, 3 + j] += c_m * 2.0 * (vv * delta - v[i] * v[j])
            Hy[6 + i, 6 + j] += c_m * 2.0 * (uu * delta - u[i] * u[j])
            huv = 2.0 * (2.0 * u[i] * v[j] - v[i] * u[j] - uv * delta)
            Hy[3 + i, 6 + j] += c_m * huv
            Hy[6 + j, 3 + i] += c_m * huv
    return f


@njit(cache=True)
def _feature(feat: int, y: np.ndarray, gy: np.ndarray, Hy: np.ndarray, order: int) -> float:
    """Feature quantity (D for point-point / point-line, signed f otherwise) and derivatives."""
    if feat == FEAT_PP:
        return _pp_squared(y, gy, Hy, order)
    if feat == FEAT_PL:
        return _pl_squared(y, gy, Hy, order)
    return _ruv_signed(y, gy, Hy, order)


@njit(cache=True)
def _finish(
    q: float, signed: bool, squared: bool, gy: np.ndarray, Hy: np.ndarray, m: int, order: int
) -> float:
    """Convert the feature quantity q (and gy[:m], Hy[:m, :m] in place) to D or d; returns it."""
    if signed:
        if squared:
            if order >= 2:
                for i in range(m):
                    for j in range(m):
                        Hy[i, j] = 2.0 * gy[i] * gy[j] + 2.0 * q * Hy[i, j]
            if order >= 1:
                for i in range(m):
                    gy[i] *= 2.0 * q
            return q * q
        sign = 1.0 if q > 0.0 else (-1.0 if q < 0.0 else 0.0)
        if order >= 1:
            for i in range(m):
                gy[i] *= sign
        if order >= 2:
            for i in range(m):
                for j in range(m):
                    Hy[i, j] *= sign
        return abs(q)
    if squared:
        return q
    d = math.sqrt(q)
    if d == 0.0:
        for i in range(m if order >= 1 else 0):
            gy[i] = 0.0
            for j in range(m if order >= 2 else 0):
                Hy[i, j] = 0.0
        return 0.0
    if order >= 2:
        inv4d3 = 0.25 / (d * d * d)
        for i in range(m):
            for j in range(m):
                Hy[i, j] = Hy[i, j] / (2.0 * d) - gy[i] * gy[j] * inv4d3
    if order >= 1:
        for i in range(m):
            gy[i] /= 2.0 * d
    return d


@njit(cache=True)
def _scatter(
    feat: int,
    blocks: np.ndarray,
    dim: int,
    gy: np.ndarray,
    Hy: np.ndarray,
    g_out: np.ndarray,
    H_out: np.ndarray,
    order: int,
) -> None:
    """g_out[slot(k)] = (C^T gy)_k and H_out[slot(k), slot(l)] = (C^T Hy C)_kl (zeroed rows)."""
    na = _NA[feat]
    nk = _NK[feat]
    for k in range(nk):
        for c in range(dim):
            acc = 0.0
            for a in range(na):
                acc += _C[feat, a, k] * gy[a * dim + c]
            g_out[blocks[k] * dim + c] = acc
    if order < 2:
        return
    for k in range(nk):
        for l in range(nk):
            for ci in range(dim):
                for cj in range(dim):
                    acc = 0.0
                    for a in range(na):
                        cak = _C[feat, a, k]
                        if cak == 0.0:
                            continue
                        for b in range(na):
                            acc += cak * _C[feat, b, l] * Hy[a * dim + ci, b * dim + cj]
                    H_out[blocks[k] * dim + ci, blocks[l] * dim + cj] = acc
