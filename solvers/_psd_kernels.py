"""numba kernels of :mod:`solvers.psd`: eigen-decomposition and PSD projection of one small block.

Private: array-in / array-out, no validation. The symmetric eigenproblem of an ``n x n`` block is
solved by Householder reduction to tridiagonal form followed by the implicit QL iteration with
Wilkinson-type shifts (EISPACK ``tred2`` / ``tql2``, in the form of the public-domain JAMA
library). For the blocks met here (n <= 12) this is several times faster than a batched LAPACK
call, whose per-matrix overhead dominates at that size, and it runs inside other kernels (the
contact terms project each pair's Hessian where they compute it).

The projection clamps the eigenvalues from below, ``P = V diag(max(w, eps)) V^T``, rebuilt from
the clamped spectrum (not as ``H`` minus its negative part, which would leave round-off of the
size of the largest negative eigenvalue in the cleared directions) and written symmetric (upper
triangle mirrored); a block whose eigenvalues are all ``>= eps`` is left untouched.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

#: Cap on QL iterations per eigenvalue (convergence is cubic; LAPACK uses 30).
_MAX_QL_ITERATIONS = 60


@njit(cache=True)
def _tred2(V: np.ndarray, d: np.ndarray, e: np.ndarray, n: int) -> None:
    """Householder tridiagonalisation of the symmetric V[:n, :n] (overwritten by the orthogonal
    transformation); diagonal to d[:n], sub-diagonal to e[1:n] (e[0] = 0)."""
    for j in range(n):
        d[j] = V[n - 1, j]
    for i in range(n - 1, 0, -1):
        scale = 0.0
        h = 0.0
        for k in range(i):
            scale += abs(d[k])
        if scale == 0.0:
            e[i] = d[i - 1]
            for j in range(i):
                d[j] = V[i - 1, j]
                V[i, j] = 0.0
                V[j, i] = 0.0
        else:
            for k in range(i):
                d[k] /= scale
                h += d[k] * d[k]
            f = d[i - 1]
            g = math.sqrt(h)
            if f > 0.0:
                g = -g
            e[i] = scale * g
            h -= f * g
            d[i - 1] = f - g
            for j in range(i):
                e[j] = 0.0
            for j in range(i):
                f = d[j]
                V[j, i] = f
                g = e[j] + V[j, j] * f
                for k in range(j + 1, i):
                    g += V[k, j] * d[k]
                    e[k] += V[k, j] * f
                e[j] = g
            f = 0.0
            for j in range(i):
                e[j] /= h
                f += e[j] * d[j]
            hh = f / (h + h)
            for j in range(i):
                e[j] -= hh * d[j]
            for j in range(i):
                f = d[j]
                g = e[j]
                for k in range(j, i):
                    V[k, j] -= f * e[k] + g * d[k]
                d[j] = V[i - 1, j]
                V[i, j] = 0.0
        d[i] = h
    # accumulate the transformations
    for i in range(n - 1):
        V[n - 1, i] = V[i, i]
        V[i, i] = 1.0
        h = d[i + 1]
        if h != 0.0:
            for k in range(i + 1):
                d[k] = V[k, i + 1] / h
            for j in range(i + 1):
                g = 0.0
                for k in range(i + 1):
                    g += V[k, i + 1] * V[k, j]
                for k in range(i + 1):
                    V[k, j] -= g * d[k]
        for k in range(i + 1):
            V[k, i + 1] = 0.0
    for j in range(n):
        d[j] = V[n - 1, j]
        V[n - 1, j] = 0.0
    V[n - 1, n - 1] = 1.0
    e[0] = 0.0


@njit(cache=True)
def _tql2(V: np.ndarray, d: np.ndarray, e: np.ndarray, n: int) -> bool:
    """Implicit QL on the tridiagonal (d, e) from :func:`_tred2`: eigenvalues to d[:n]
    (unsorted), eigenvectors to the columns of V[:n, :n]. False if an eigenvalue failed to
    converge within ``_MAX_QL_ITERATIONS``."""
    for i in range(1, n):
        e[i - 1] = e[i]
    e[n - 1] = 0.0
    f = 0.0
    tst1 = 0.0
    eps = 2.0**-52
    for l in range(n):
        tst1 = max(tst1, abs(d[l]) + abs(e[l]))
        m = l
        while m < n - 1:  # e[n - 1] = 0 ends the search
            if abs(e[m]) <= eps * tst1:
                break
            m += 1
        if m > l:
            it = 0
            while True:
                it += 1
                if it > _MAX_QL_ITERATIONS:
                    return False
                g = d[l]
                p = (d[l + 1] - g) / (2.0 * e[l])
                r = math.hypot(p, 1.0)
                if p < 0.0:
                    r = -r
                d[l] = e[l] / (p + r)
                d[l + 1] = e[l] * (p + r)
                dl1 = d[l + 1]
                h = g - d[l]
                for i in range(l + 2, n):
                    d[i] -= h
                f += h
                p = d[m]
                c = 1.0
                c2 = c
                c3 = c
                el1 = e[l + 1]
                s = 0.0
                s2 = 0.0
                for i in range(m - 1, l - 1, -1):
                    c3 = c2
                    c2 = c
                    s2 = s
                    g = c * e[i]
                    h = c * p
                    r = math.hypot(p, e[i])
                    e[i + 1] = s * r
                    s = e[i] / r
                    c = p / r
                    p = c * d[i] - s * g
                    d[i + 1] = h + s * (c * g + s * d[i])
                    for k in range(n):
                        h = V[k, i + 1]
                        V[k, i + 1] = s * V[k, i] + c * h
                        V[k, i] = c * V[k, i] - s * h
                p = -s * s2 * c3 * el1 * e[l] / dl1
                e[l] = s * p
                d[l] = c * p
                if not abs(e[l]) > eps * tst1:
                    break
        d[l] += f
        e[l] = 0.0
    return True


@njit(cache=True)
def _symmetric_eigen(A: np.ndarray, n: int, V: np.ndarray, w: np.ndarray, e: np.ndarray) -> bool:
    """Eigen-decomposition of the symmetric part of A[:n, :n]: eigenvalues w[:n] (unsorted),
    eigenvectors the columns of V[:n, :n]; e (>= n) is workspace. False if A is not finite or
    the iteration did not converge."""
    for i in range(n):
        for j in range(n):
            a = 0.5 * (A[i, j] + A[j, i])
            if not math.isfinite(a):
                return False
            V[i, j] = a
    if n == 1:
        w[0] = V[0, 0]
        V[0, 0] = 1.0
        return True
    _tred2(V, w, e, n)
    return _tql2(V, w, e, n)


@njit(cache=True, inline="always")
def _symmetric_eigen_2x2(A: np.ndarray, V: np.ndarray, w: np.ndarray) -> bool:
    """Closed-form :func:`_symmetric_eigen` for n = 2 (same contract, no workspace).

    For the symmetric part [[a, b], [b, c]]: w = m -/+ r with m = (a + c)/2,
    r = hypot((a - c)/2, b); the eigenvector of m + r is (cos t, sin t), tan 2t = 2b/(a - c).
    Absolute accuracy is eps |A|, as for the QL iteration.
    """
    a = A[0, 0]
    c = A[1, 1]
    b = 0.5 * (A[0, 1] + A[1, 0])
    if not (math.isfinite(a) and math.isfinite(b) and math.isfinite(c)):
        return False
    m = 0.5 * (a + c)
    h = 0.5 * (a - c)
    r = math.hypot(h, b)
    w[0] = m - r
    w[1] = m + r
    t = 0.5 * math.atan2(b, h)  # atan2(0, 0) = 0: the identity for a multiple of I
    ct = math.cos(t)
    st = math.sin(t)
    V[0, 1] = ct
    V[1, 1] = st
    V[0, 0] = -st
    V[1, 0] = ct
    return True


@njit(cache=True)
def _project_block(
    A: np.ndarray, n: int, eps: float, V: np.ndarray, w: np.ndarray, e: np.ndarray
) -> bool:
    """Clamp the eigenvalues of the symmetric part of A[:n, :n] from below at ``eps``, in place.

    Returns whether A changed. Blocks with every eigenvalue ``>= eps`` are left as they are;
    others become ``V diag(max(w, eps)) V^T`` with the upper triangle mirrored (exactly
    symmetric). A non-finite or non-converged block is filled with NaN.
    V (>= n, >= n), w and e (>= n) are workspace.
    """
    if not _symmetric_eigen(A, n, V, w, e):
        for i in range(n):
            for j in range(n):
                A[i, j] = np.nan
        return True
    neg = False
    for k in range(n):
        if w[k] < eps:
            neg = True
    if not neg:
        return False
    for k in range(n):
        w[k] = max(w[k], eps)
    for i in range(n):
        for j in range(i, n):
            acc = 0.0
            for k in range(n):
                if w[k] != 0.0:
                    acc += w[k] * V[i, k] * V[j, k]
            A[i, j] = acc
            A[j, i] = acc
    return True


#: Blocks per parallel chunk of :func:`_project_stack` (each chunk has its own workspace).
_CHUNK = 256


@njit(cache=True, parallel=True)
def _project_stack(blocks: np.ndarray, eps: float) -> None:
    """:func:`_project_block` on every block of a C-contiguous stack (S, n, n), in place."""
    n_blocks, n = blocks.shape[0], blocks.shape[1]
    for chunk in prange((n_blocks + _CHUNK - 1) // _CHUNK):
        V = np.empty((n, n))
        w = np.empty(n)
        e = np.empty(n)
        for s in range(chunk * _CHUNK, min(n_blocks, (chunk + 1) * _CHUNK)):
            _project_block(blocks[s], n, eps, V, w, e)
