"""numba kernels: per-pair barrier gradients and (PSD-projected) Hessians w.r.t. the pair's points.

For a pair with distance d(x) (x: the pair's m points, m d coordinates) the barrier term is
c b(d(x)) (c = omega times the duplicate-removal coefficient), so with c1 = c b'(d), c2 = c b''(d)

    grad = c1 grad d,        H = c2 grad d grad d^T + c1 hess d.

The distance kernels (:mod:`geometry._distance_kernels`) give grad d and hess d in the difference
coordinates y = C x of the pair's closest feature (at most three difference vectors: na d <= 9
entries), and ``x``-space quantities are pulled back by C: H = C^T H_y C. Every such matrix
vanishes on rigid translations (the rows of C sum to zero), so its eigenvectors of non-zero
eigenvalue lie in the row space of C. With the thin QR factorisation C^T = Q R (Q orthonormal,
R na x na, both Kronecker products with the d x d identity) H = Q M Q^T with M = R H_y R^T, and
the PSD projection (clamping negative eigenvalues, BFEMP section 5) of H is Q proj(M) Q^T =
C^T R^-1 proj(M) R^-T C: the projection of the full (m d)^2 block, computed on an (na d)^2 one
(point-triangle: 9 x 9 instead of 12 x 12; 2D point-edge: 4 x 4 instead of 6 x 6).

Private: array-in / array-out, no validation; ``pos (C, d)`` collision positions in m,
``pair_points (n, m)`` collision-point indices, ``c1, c2 (n,)`` the scaled barrier derivatives.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from geometry._distance_features import _C, _NA, _NK, _scatter
from geometry._distance_kernels import _BLOCKS, _FEATURE, _classify, _pair_derivatives
from solvers._psd_kernels import _project_block


def _reductions() -> tuple[np.ndarray, np.ndarray]:
    """R and R^-1 (per feature, na x na, zero-padded to 3 x 3) of the thin QR of C^T."""
    r_all = np.zeros((_C.shape[0], 3, 3))
    rinv_all = np.zeros((_C.shape[0], 3, 3))
    for feat in range(_C.shape[0]):
        na, nk = _NA[feat], _NK[feat]
        r = np.linalg.qr(_C[feat, :na, :nk].T, mode="r")
        r_all[feat, :na, :na] = r
        rinv_all[feat, :na, :na] = np.linalg.inv(r)
    return r_all, rinv_all


_R, _RINV = _reductions()


@njit(cache=True)
def _pair_distances(pos: np.ndarray, pair_points: np.ndarray, kind: int) -> np.ndarray:
    """Unsigned distances ``(n,)`` in m of the pairs (kind: ``geometry`` KIND_*, any kind)."""
    n, m = pair_points.shape
    dim = pos.shape[1]
    out = np.empty(n)
    X = np.empty((m, dim))
    for i in range(n):
        for a in range(m):
            for c in range(dim):
                X[a, c] = pos[pair_points[i, a], c]
        out[i] = np.sqrt(_classify(X, kind)[1])
    return out


@njit(cache=True)
def _congruence(T: np.ndarray, na: int, dim: int, A: np.ndarray, out: np.ndarray) -> None:
    """out = (T (x) I_d) A (T (x) I_d)^T for T (na, na) and A, out (na d, na d)."""
    for a in range(na):
        for b in range(na):
            for i in range(dim):
                for j in range(dim):
                    acc = 0.0
                    for p in range(na):
                        tap = T[a, p]
                        if tap == 0.0:
                            continue
                        for q in range(na):
                            acc += tap * T[b, q] * A[p * dim + i, q * dim + j]
                    out[a * dim + i, b * dim + j] = acc


@njit(cache=True)
def _barrier_gradients(
    pos: np.ndarray, pair_points: np.ndarray, kind: int, c1: np.ndarray
) -> np.ndarray:
    """Local gradients ``(n, m d)`` c1 grad d of the pairs (kind: ``geometry`` KIND_*)."""
    n, m = pair_points.shape
    dim = pos.shape[1]
    out = np.zeros((n, m * dim))
    X = np.empty((m, dim))
    y = np.empty((3, dim))
    gy = np.empty(3 * dim)
    Hy = np.empty((3 * dim, 3 * dim))
    no_hess = np.empty((0, 0))
    for i in range(n):
        for a in range(m):
            for c in range(dim):
                X[a, c] = pos[pair_points[i, a], c]
        typ = _pair_derivatives(X, kind, False, 1, y, gy, Hy)[1]
        feat = _FEATURE[kind, typ]
        for j in range(_NA[feat] * dim):
            gy[j] *= c1[i]
        _scatter(feat, _BLOCKS[kind, typ], dim, gy, no_hess, out[i], no_hess, 1)
    return out


#: Pairs per parallel chunk of :func:`_barrier_hessians` (each chunk has its own workspace).
_CHUNK = 512


@njit(cache=True, parallel=True)
def _barrier_hessians(
    pos: np.ndarray,
    pair_points: np.ndarray,
    kind: int,
    c1: np.ndarray,
    c2: np.ndarray,
    psd: bool,
) -> np.ndarray:
    """Local Hessians ``(n, m d, m d)`` c2 grad d grad d^T + c1 hess d of the pairs, each
    projected to PSD (eigenvalues clamped at 0) when ``psd`` (then a non-finite block becomes
    NaN); exactly symmetric. Chunks of pairs run in parallel, each writing its own rows of the
    output."""
    n, m = pair_points.shape
    dim = pos.shape[1]
    out = np.zeros((n, m * dim, m * dim))
    for chunk in prange((n + _CHUNK - 1) // _CHUNK):
        X = np.empty((m, dim))
        y = np.empty((3, dim))
        gy = np.empty(3 * dim)
        Hy = np.empty((3 * dim, 3 * dim))
        M = np.empty((3 * dim, 3 * dim))
        V = np.empty((3 * dim, 3 * dim))
        w = np.empty(3 * dim)
        e = np.empty(3 * dim)
        g_dummy = np.empty(m * dim)
        for i in range(chunk * _CHUNK, min(n, (chunk + 1) * _CHUNK)):
            for a in range(m):
                for c in range(dim):
                    X[a, c] = pos[pair_points[i, a], c]
            typ = _pair_derivatives(X, kind, False, 2, y, gy, Hy)[1]
            feat = _FEATURE[kind, typ]
            na = _NA[feat]
            k = na * dim
            for r in range(k):
                for s in range(k):
                    Hy[r, s] = c2[i] * gy[r] * gy[s] + c1[i] * Hy[r, s]
            if psd:
                _congruence(_R[feat], na, dim, Hy, M)
                if _project_block(M, k, 0.0, V, w, e):
                    _congruence(_RINV[feat], na, dim, M, Hy)
            _scatter(feat, _BLOCKS[kind, typ], dim, gy, Hy, g_dummy, out[i], 2)
            for r in range(m * dim):  # C^T H C sums in another order below the diagonal
                for s in range(r + 1, m * dim):
                    out[i, s, r] = out[i, r, s]
    return out
