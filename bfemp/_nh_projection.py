"""PSD projection of the Neo-Hookean dP/dF by its analytic eigensystem (numba).

For psi = mu/2 (|F|^2 - d) - mu log J + lam/2 log^2 J the derivative is (``_material_kernels``)

    dP_ij/dF_kl = mu d_ik d_jl + a G_il G_kj + lam G_ij G_kl,   G = F^{-T},  a = mu - lam log J.

With the singular value decomposition F = U diag(s) V^T (so G = U diag(1/s) V^T) and the
rotated coordinates dF = U dF^ V^T, the three terms become block diagonal (as for every
isotropic energy, Smith, de Goes and Kim, "Analytic eigensystems for isotropic distortion
energies", ACM TOG 2019):

- the d "scaling" directions dF^ = e_a e_a^T see the d x d matrix
  ``S = mu I + a diag(1/s_a^2) + lam w w^T`` with w_a = 1/s_a;
- each pair a < b couples dF^_ab with dF^_ba by ``[[mu, c], [c, mu]]``, c = a / (s_a s_b): the
  "twist" and "flip" eigenpairs mu -/+ c with eigenvectors (u_a v_b^T -/+ u_b v_a^T) / sqrt 2.

The projection clamps these d^2 eigenvalues at 0 and rebuilds sum_k lambda_k q_k q_k^T: the
same matrix as the generic projection (``solvers.psd``, the unique nearest PSD matrix in the
Frobenius norm) for the cost of a d x d eigenproblem instead of a d^2 x d^2 one. A block whose
eigenvalues are all >= 0 is left as it is. The SVD comes from the eigen-decomposition of F^T F
(V; then s_a = |F v_a| and U = F V / s); where F is far from conditioned (s_min < 1e-4 s_max) the
generic projection of the block is used instead.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from solvers._psd_kernels import _project_block, _symmetric_eigen, _symmetric_eigen_2x2

__all__ = ["project_nh_derivative"]

#: singular-value ratio below which the block falls back to the generic projection
_MIN_SINGULAR_RATIO = 1e-4
_CHUNK = 256


@njit(inline="always")
def _small_eigen(A: np.ndarray, d: int, V: np.ndarray, w: np.ndarray, e: np.ndarray) -> bool:
    """Eigenpairs of a symmetric d x d matrix: closed form for d = 2, QL iteration otherwise."""
    if d == 2:
        return _symmetric_eigen_2x2(A, V, w)
    return _symmetric_eigen(A, d, V, w, e)


@njit(inline="always")
def _project_one(
    d: int,
    A: np.ndarray,
    F: np.ndarray,
    lam: float,
    mu: float,
    C: np.ndarray,
    V: np.ndarray,
    U: np.ndarray,
    s: np.ndarray,
    e: np.ndarray,
    S: np.ndarray,
    Q: np.ndarray,
    w: np.ndarray,
    W: np.ndarray,
    ws: np.ndarray,
    es: np.ndarray,
    q: np.ndarray,
) -> None:
    """Project one block A (d*d, d*d) in place; ``d`` is a literal at each call site."""
    n = d * d
    for i in range(d):
        for j in range(d):
            acc = 0.0
            for k in range(d):
                acc += F[k, i] * F[k, j]
            C[i, j] = acc
    if not _small_eigen(C, d, V, s, e):
        _project_block(A, n, 0.0, W, ws, es)
        return
    # s_a = |F v_a|, not sqrt of the eigenvalue of F^T F: the square root of a small eigenvalue
    # keeps only eps s_max^2 / s_min^2 of relative precision (3e-8 at s_min = 1e-4 s_max,
    # measured against the generic projection), the norm eps s_max / s_min
    s_max = 0.0
    s_min = math.inf
    for a in range(d):
        norm2 = 0.0
        for i in range(d):
            acc = 0.0
            for k in range(d):
                acc += F[i, k] * V[k, a]
            U[i, a] = acc
            norm2 += acc * acc
        s[a] = math.sqrt(norm2)
        s_max = max(s_max, s[a])
        s_min = min(s_min, s[a])
    det = 1.0
    for a in range(d):
        det *= s[a]
    if not (s_min > _MIN_SINGULAR_RATIO * s_max and det > 0.0):
        _project_block(A, n, 0.0, W, ws, es)
        return
    for i in range(d):
        for a in range(d):
            U[i, a] /= s[a]
    coef = mu - lam * math.log(det)  # J = det F = prod s (det F > 0 for a finite block)
    # the scaling block and its eigenpairs
    for a in range(d):
        for b in range(d):
            S[a, b] = lam / (s[a] * s[b])
        S[a, a] += mu + coef / (s[a] * s[a])
    if not _small_eigen(S, d, Q, w, e):
        _project_block(A, n, 0.0, W, ws, es)
        return
    negative = False
    for a in range(d):
        if w[a] < 0.0:
            negative = True
    for a in range(d):
        for b in range(a + 1, d):
            if mu - abs(coef) / (s[a] * s[b]) < 0.0:
                negative = True
    if not negative:
        return
    for i in range(n):
        for j in range(n):
            A[i, j] = 0.0
    # scaling eigenvectors q = vec(U diag(Q[:, k]) V^T)
    for k in range(d):
        lk = w[k]
        if lk <= 0.0:
            continue
        for i in range(d):
            for j in range(d):
                acc = 0.0
                for a in range(d):
                    acc += U[i, a] * Q[a, k] * V[j, a]
                q[i * d + j] = acc
        for r in range(n):
            for c in range(r, n):
                A[r, c] += lk * q[r] * q[c]
    # twist and flip: (u_a v_b^T -/+ u_b v_a^T) / sqrt 2, eigenvalues mu -/+ c
    inv_sqrt2 = 1.0 / math.sqrt(2.0)
    for a in range(d):
        for b in range(a + 1, d):
            c_ab = coef / (s[a] * s[b])
            for sign in (-1.0, 1.0):
                lk = mu + sign * c_ab
                if lk <= 0.0:
                    continue
                for i in range(d):
                    for j in range(d):
                        q[i * d + j] = inv_sqrt2 * (U[i, a] * V[j, b] + sign * U[i, b] * V[j, a])
                for r in range(n):
                    for c in range(r, n):
                        A[r, c] += lk * q[r] * q[c]
    for r in range(n):
        for c in range(r + 1, n):
            A[c, r] = A[r, c]


@njit(inline="always")
def _project_stack(
    d: int, blocks: np.ndarray, F: np.ndarray, mu: np.ndarray, lam: np.ndarray
) -> None:
    """_project_one on every block of (S, d*d, d*d), in parallel chunks with their workspace."""
    n_s = F.shape[0]
    n = d * d
    for chunk in prange((n_s + _CHUNK - 1) // _CHUNK):
        C = np.empty((d, d))
        V = np.empty((d, d))
        U = np.empty((d, d))
        s = np.empty(d)
        e = np.empty(d)
        S = np.empty((d, d))
        Q = np.empty((d, d))
        w = np.empty(d)
        W = np.empty((n, n))
        ws = np.empty(n)
        es = np.empty(n)
        q = np.empty(n)
        for k in range(chunk * _CHUNK, min(n_s, (chunk + 1) * _CHUNK)):
            block = blocks[k]
            finite = True
            for i in range(n):
                for j in range(n):
                    if not math.isfinite(block[i, j]):
                        finite = False
            if not finite:
                _project_block(block, n, 0.0, W, ws, es)  # fills it with NaN
                continue
            _project_one(d, block, F[k], lam[k], mu[k], C, V, U, s, e, S, Q, w, W, ws, es, q)


# one compiled kernel per dimension, d a constant (numba unrolls the d-loops)
@njit(cache=True, parallel=True)
def _project_stack_2d(blocks: np.ndarray, F: np.ndarray, mu: np.ndarray, lam: np.ndarray) -> None:
    _project_stack(2, blocks, F, mu, lam)


@njit(cache=True, parallel=True)
def _project_stack_3d(blocks: np.ndarray, F: np.ndarray, mu: np.ndarray, lam: np.ndarray) -> None:
    _project_stack(3, blocks, F, mu, lam)


def project_nh_derivative(
    blocks: np.ndarray, F: np.ndarray, mu: np.ndarray, lam: np.ndarray
) -> np.ndarray:
    """The PSD projection of Neo-Hookean dP/dF blocks (module docstring).

    Args:
        blocks: dP/dF at F, ``(S, d*d, d*d)`` in Pa (row i*d + j, column k*d + l), not modified.
        F: the deformation gradients ``(S, d, d)``.
        mu, lam: the Lame parameters ``(S,)`` in Pa.

    Returns:
        New array ``(S, d*d, d*d)``: each block with its negative eigenvalues set to 0 (blocks
        with none returned unchanged); NaN for a non-finite block.
    """
    out = np.array(blocks, dtype=np.float64, order="C", copy=True)
    kernel = {2: _project_stack_2d, 3: _project_stack_3d}.get(F.shape[-1])
    if kernel is None or F.shape[1:] != (F.shape[-1],) * 2:
        raise ValueError(f"F must be (S, 2, 2) or (S, 3, 3), got {F.shape}")
    if out.shape[0]:
        kernel(
            out,
            np.ascontiguousarray(F, dtype=np.float64),
            np.ascontiguousarray(mu, dtype=np.float64),
            np.ascontiguousarray(lam, dtype=np.float64),
        )
    return out
