"""numba kernels of the logistic-regression (LR) multimaterial contact (Nairn et al., "LR"),
2D and 3D: the LR plane and separation at contact nodes (LR section 3.1, LR eqs. 19-25, Appendix
LR eqs. 53-57) and the deformed particle radius (LR eq. 25); the per-material grid moments are
in ``_lr_grid_kernels``.

Race-freedom: the LR solve writes only row c of its outputs (parallel over contact nodes from
``PARALLEL_MIN`` nodes on, else serial, with identical results).

Error codes of the LR solve (``code (C,)``): 0 ok, 1 the cloud lacks one class (or is empty),
2 the linear-regression start is degenerate (singular system or zero normal).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from bfemp._njit import serial_or_parallel

#: contact nodes from which the LR solves run in parallel (below, the thread start-up costs more
#: than the loop)
PARALLEL_MIN = 64

OK = 0
ONE_CLASS = 1
DEGENERATE = 2


@njit(cache=True)
def _solve_small(A: np.ndarray, b: np.ndarray, n: int) -> bool:
    """Solve ``A x = b`` (n x n, n <= 4) in place by Gaussian elimination with partial pivoting;
    the solution replaces ``b``. False when a pivot is zero or not finite."""
    for k in range(n):
        piv = k
        big = abs(A[k, k])
        for r in range(k + 1, n):
            if abs(A[r, k]) > big:
                big = abs(A[r, k])
                piv = r
        if not (big > 0.0) or not math.isfinite(big):
            return False
        if piv != k:
            for c in range(n):
                t = A[k, c]
                A[k, c] = A[piv, c]
                A[piv, c] = t
            t = b[k]
            b[k] = b[piv]
            b[piv] = t
        for r in range(k + 1, n):
            f = A[r, k] / A[k, k]
            for c in range(k, n):
                A[r, c] -= f * A[k, c]
            b[r] -= f * b[k]
    for k in range(n - 1, -1, -1):
        s = b[k]
        for c in range(k + 1, n):
            s -= A[k, c] * b[c]
        b[k] = s / A[k, k]
        if not math.isfinite(b[k]):
            return False
    return True


@njit(cache=True)
def radius_along(F: np.ndarray, R0: np.ndarray, n: np.ndarray) -> float:
    """Deformed radius R_p of one particle along the unit normal ``n (d,)`` in m (LR eq. 25):
    n0 = F^-1 n, 1/R_p = sqrt(sum_k n0_k^2 / R0_k^2): the distance from the centre to the
    boundary of the inscribed ellipse (ellipsoid) of semi-axes ``R0 (d,)`` mapped by
    ``F (d, d)``, along n. R0 = 0 (a surface sample) gives 0."""
    d = n.shape[0]
    for k in range(d):
        if R0[k] == 0.0:
            return 0.0
    n0 = np.empty(d)
    if d == 2:
        det = F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]
        n0[0] = (F[1, 1] * n[0] - F[0, 1] * n[1]) / det
        n0[1] = (-F[1, 0] * n[0] + F[0, 0] * n[1]) / det
    else:  # d == 3: n0 = adj(F) n / det F
        c00 = F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1]
        c01 = F[0, 2] * F[2, 1] - F[0, 1] * F[2, 2]
        c02 = F[0, 1] * F[1, 2] - F[0, 2] * F[1, 1]
        c10 = F[1, 2] * F[2, 0] - F[1, 0] * F[2, 2]
        c11 = F[0, 0] * F[2, 2] - F[0, 2] * F[2, 0]
        c12 = F[0, 2] * F[1, 0] - F[0, 0] * F[1, 2]
        c20 = F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0]
        c21 = F[0, 1] * F[2, 0] - F[0, 0] * F[2, 1]
        c22 = F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]
        det = F[0, 0] * c00 + F[0, 1] * c10 + F[0, 2] * c20
        n0[0] = (c00 * n[0] + c01 * n[1] + c02 * n[2]) / det
        n0[1] = (c10 * n[0] + c11 * n[1] + c12 * n[2]) / det
        n0[2] = (c20 * n[0] + c21 * n[1] + c22 * n[2]) / det
    s = 0.0
    for k in range(d):
        s += (n0[k] / R0[k]) ** 2
    return 1.0 / math.sqrt(s)


@njit(cache=True)
def deformed_radii(F: np.ndarray, R0: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """R_p ``(Q,)`` in m of ``F (Q, d, d)``, ``R0 (Q, d)`` m along ``normal (Q, d)`` (LR eq. 25)."""
    q = F.shape[0]
    out = np.empty(q)
    for p in range(q):
        out[p] = radius_along(F[p], R0[p], normal[p])
    return out


@njit(cache=True)
def _logistic(s: float) -> tuple[float, float]:
    """The scaled logistic f(s) = 2 / (1 + e^-s) - 1 = tanh(s/2) (LR eq. 20) and its derivative
    psi(s) = 2 e^-s / (1 + e^-s)^2 (LR eq. 53), both without overflow."""
    e = math.exp(-abs(s))
    return math.tanh(0.5 * s), 2.0 * e / ((1.0 + e) * (1.0 + e))


@njit(cache=True)
def _drop_thin_directions(
    lo: int, hi: int, cloud_idx: np.ndarray, points_x: np.ndarray, thin_sq: float, n: np.ndarray
) -> None:
    """Remove from the unit normal n (d,) its components along the principal directions in
    which the whole cloud is thinner than sqrt(thin_sq) (standard deviation, m), then
    renormalise; n is left alone if nothing of it remains.

    Why (bfemp's; LR is silent, pitfall L-P9): a B-spline cloud reaches 1.5 cells, so a node
    just outside a body's side sees one column of particles of each material. Such a cloud
    holds no information across the column, yet the two columns are offset sideways by the
    bodies' different bulging (0.09 mm at 10 % strain in ``lr_compression``), which separates
    the classes exactly: the linear start and the logistic fit then took the sideways normal,
    the normal approach went uncorrected there, and the column edges interpenetrated.
    """
    d = n.shape[0]
    count = hi - lo
    if count < 2:
        return
    mean = np.zeros(d)
    for j in range(lo, hi):
        for a in range(d):
            mean[a] += points_x[cloud_idx[j], a]
    for a in range(d):
        mean[a] /= count
    cov = np.zeros((d, d))
    for j in range(lo, hi):
        p = cloud_idx[j]
        for a in range(d):
            for b in range(d):
                cov[a, b] += (points_x[p, a] - mean[a]) * (points_x[p, b] - mean[b])
    for a in range(d):
        for b in range(d):
            cov[a, b] /= count
    values, vectors = np.linalg.eigh(cov)
    q = n.copy()
    for k in range(d):
        if values[k] < thin_sq:
            dot = 0.0
            for a in range(d):
                dot += q[a] * vectors[a, k]
            for a in range(d):
                q[a] -= dot * vectors[a, k]
    length = 0.0
    for a in range(d):
        length += q[a] * q[a]
    length = math.sqrt(length)
    if length > 1e-3:
        for a in range(d):
            n[a] = q[a] / length


@njit(cache=True)
def _lr_node(
    c: int,
    node_x: np.ndarray,
    cloud_ptr: np.ndarray,
    cloud_idx: np.ndarray,
    cloud_side: np.ndarray,
    points_x: np.ndarray,
    points_F: np.ndarray,
    points_R0: np.ndarray,
    lam: float,
    tol: float,
    max_iterations: int,
    linear_scale: float,
    thin_sq: float,
    normal_start: np.ndarray,
    has_start: np.ndarray,
    out_normal: np.ndarray,
    out_phi: np.ndarray,
    out_sep: np.ndarray,
    out_iter: np.ndarray,
    out_conv: np.ndarray,
    out_fb: np.ndarray,
    out_code: np.ndarray,
) -> None:
    """The LR plane and separation of contact node c; writes row c of the outputs only."""
    d = node_x.shape[1]
    m = d + 1
    lo = cloud_ptr[c]
    hi = cloud_ptr[c + 1]
    n_alpha = 0
    n_beta = 0
    for j in range(lo, hi):
        if cloud_side[j] < 0:
            n_alpha += 1
        else:
            n_beta += 1
    if n_alpha == 0 or n_beta == 0:
        out_code[c] = ONE_CLASS
        return
    xt = np.empty(m)  # x~_p = (X_p - x_i, 1): positions relative to the node (NairnMPM)
    xt[d] = 1.0
    A = np.empty((m, m))
    b = np.empty(m)
    phi = np.empty(m)
    phi_one = np.empty(m)
    n_lin = np.empty(d)
    prev = np.empty(d)
    n_new = np.empty(d)

    # Linear regression (LR App.: phi(0) = 0 makes the first NLLS step a linear fit):
    # (X~^T X~ + Lambda) phi_lin = X~^T c, Lambda = lam (1, .., 1, 0), then phi(1) = scale phi_lin.
    A[:, :] = 0.0
    b[:] = 0.0
    for j in range(lo, hi):
        p = cloud_idx[j]
        cp = 1.0 if cloud_side[j] > 0 else -1.0
        for a in range(d):
            xt[a] = points_x[p, a] - node_x[c, a]
        for r in range(m):
            b[r] += cp * xt[r]
            for s in range(r, m):
                A[r, s] += xt[r] * xt[s]
    for r in range(m):
        for s in range(r):
            A[r, s] = A[s, r]
    for a in range(d):
        A[a, a] += lam
    if not _solve_small(A, b, m):
        out_code[c] = DEGENERATE
        return
    nrm = 0.0
    for a in range(d):
        nrm += b[a] * b[a]
    nrm = math.sqrt(nrm)
    if not (nrm > 0.0) or not math.isfinite(nrm):
        out_code[c] = DEGENERATE
        return
    for a in range(d):
        n_lin[a] = b[a] / nrm
    for r in range(m):
        phi[r] = linear_scale * b[r]
        phi_one[r] = phi[r]

    if has_start[c]:
        # Warm start (LR App., optional): the start normal at the linear fit's magnitude, and the
        # offset that fits the (scaled) linear model best for it.
        ns = 0.0
        for a in range(d):
            ns += normal_start[c, a] ** 2
        ns = math.sqrt(ns)
        scale = linear_scale * nrm / ns
        for a in range(d):
            phi[a] = scale * normal_start[c, a]
        off = 0.0
        for j in range(lo, hi):
            p = cloud_idx[j]
            cp = 1.0 if cloud_side[j] > 0 else -1.0
            s = linear_scale * cp
            for a in range(d):
                s -= (points_x[p, a] - node_x[c, a]) * phi[a]
            off += s
        phi[d] = off / (hi - lo)
        for a in range(d):
            prev[a] = normal_start[c, a] / ns
    else:
        for a in range(d):
            prev[a] = n_lin[a]

    # Gauss-Newton on the logistic model (LR eqs. 20-21, 53-56), w_p = 1:
    # phi += (J^T J + Lambda)^-1 (J^T (c - f) - Lambda phi), J_pj = psi_p x~_pj.
    it = 0
    converged = False
    fallback = False
    while it < max_iterations:
        A[:, :] = 0.0
        for r in range(d):
            b[r] = -lam * phi[r]
        b[d] = 0.0
        for j in range(lo, hi):
            p = cloud_idx[j]
            cp = 1.0 if cloud_side[j] > 0 else -1.0
            dot = phi[d]
            for a in range(d):
                xt[a] = points_x[p, a] - node_x[c, a]
                dot += xt[a] * phi[a]
            f, psi = _logistic(dot)
            g = psi * (cp - f)
            psi2 = psi * psi
            for r in range(m):
                b[r] += g * xt[r]
                for s in range(r, m):
                    A[r, s] += psi2 * xt[r] * xt[s]
        for r in range(m):
            for s in range(r):
                A[r, s] = A[s, r]
        for a in range(d):
            A[a, a] += lam
        it += 1
        if not _solve_small(A, b, m):
            fallback = True
            break
        for r in range(m):
            phi[r] += b[r]
        nrm = 0.0
        for a in range(d):
            nrm += phi[a] * phi[a]
        nrm = math.sqrt(nrm)
        if not (nrm > 0.0) or not math.isfinite(nrm) or not math.isfinite(phi[d]):
            fallback = True
            break
        cosine = 0.0
        for a in range(d):
            n_new[a] = phi[a] / nrm
            cosine += n_new[a] * prev[a]
            prev[a] = n_new[a]
        if 1.0 - cosine < tol:  # LR eq. 57: 1 - cos(dtheta) ~ dtheta^2 / 2
            converged = True
            break

    if fallback:  # NaN or zero normal: the linear-regression normal (NairnMPM)
        for a in range(d):
            prev[a] = n_lin[a]
        for r in range(m):
            phi[r] = phi_one[r]
    if thin_sq > 0.0:
        _drop_thin_directions(lo, hi, cloud_idx, points_x, thin_sq, prev)
    for a in range(d):
        out_normal[c, a] = prev[a]
    for r in range(m):
        out_phi[c, r] = phi[r]
    out_iter[c] = it
    out_conv[c] = converged
    out_fb[c] = fallback

    # Separation (LR eqs. 22-24), relative to the node (x_i drops out of the difference):
    # d_LR = min_beta((X_p - x_i).n - R_p) - max_alpha((X_p - x_i).n + R_p), R_p of LR eq. 25.
    top_alpha = -np.inf
    bottom_beta = np.inf
    for j in range(lo, hi):
        p = cloud_idx[j]
        proj = 0.0
        for a in range(d):
            proj += (points_x[p, a] - node_x[c, a]) * prev[a]
        r_p = radius_along(points_F[p], points_R0[p], prev)
        if cloud_side[j] < 0:
            if proj + r_p > top_alpha:
                top_alpha = proj + r_p
        elif proj - r_p < bottom_beta:
            bottom_beta = proj - r_p
    out_sep[c] = bottom_beta - top_alpha
    out_code[c] = OK


@serial_or_parallel(PARALLEL_MIN)
def lr_planes_kernel(node_x: np.ndarray, *inputs: object) -> tuple[np.ndarray, ...]:
    """LR solves at the C contact nodes (validated inputs: ``inputs`` are the arguments of
    ``_lr_node`` between ``node_x`` and its outputs): ``(normal (C, d), phi (C, d+1),
    separation (C,), iterations (C,), converged (C,), fallback (C,), code (C,))``; each node
    writes only its own rows."""
    n_c, d = node_x.shape
    out_normal = np.zeros((n_c, d))
    out_phi = np.zeros((n_c, d + 1))
    out_sep = np.zeros(n_c)
    out_iter = np.zeros(n_c, dtype=np.int64)
    out_conv = np.zeros(n_c, dtype=np.bool_)
    out_fb = np.zeros(n_c, dtype=np.bool_)
    out_code = np.zeros(n_c, dtype=np.int64)
    for c in prange(n_c):  # a plain range in the serial build
        _lr_node(
            c, node_x, *inputs, out_normal, out_phi, out_sep, out_iter, out_conv, out_fb, out_code
        )
    return out_normal, out_phi, out_sep, out_iter, out_conv, out_fb, out_code
