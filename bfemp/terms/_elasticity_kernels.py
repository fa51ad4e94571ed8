"""numba kernels of the elasticity term: F from stencils, force scatter, local Hessians.

A stencil s has k nodes; its deformation gradient is affine in their positions y (m):
    F_s = C_s + sum_a y_{n(s,a)} g_{s,a}^T,
with g (1/m) the shape-function gradients (FEM, eq. 24) or F^n-weighted B-spline gradients (MPM).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True, parallel=True)
def _deformation_gradients(y, nodes, grads, const):  # noqa: ANN001, ANN202
    """F (S, d, d) = const + sum_a outer(y[nodes[s, a]], grads[s, a])."""
    n_s, k = nodes.shape
    d = y.shape[1]
    out = np.empty((n_s, d, d))
    for s in prange(n_s):
        for i in range(d):
            for j in range(d):
                acc = const[s, i, j]
                for a in range(k):
                    acc += y[nodes[s, a], i] * grads[s, a, j]
                out[s, i, j] = acc
    return out


@njit(cache=True)
def _scatter_forces(out, nodes, grads, stress_volume):  # noqa: ANN001, ANN202
    """out[nodes[s, a]] += (V P)_s g_{s, a}: dPsi/dy by the chain rule dF/dy_a = (.) g_a^T."""
    n_s, k = nodes.shape
    d = out.shape[1]
    for s in range(n_s):
        for a in range(k):
            node = nodes[s, a]
            for i in range(d):
                acc = 0.0
                for j in range(d):
                    acc += stress_volume[s, i, j] * grads[s, a, j]
                out[node, i] += acc


@njit(cache=True, parallel=True)
def _local_hessians(dpdf, grads, volume):  # noqa: ANN001, ANN202
    """H (S, k d, k d): H[a d + i, b d + j] = V sum_{m, l} dP_{i m, j l} g_{a m} g_{b l}.

    ``dpdf`` is (S, d*d, d*d) with row index i*d + m and column index j*d + l (dP_im / dF_jl).
    """
    n_s, k, d = grads.shape
    n = k * d
    out = np.empty((n_s, n, n))
    tmp = np.empty((n_s, d * d, n))  # dP . (e_j g_b^T): contract the column side first
    for s in prange(n_s):
        for r in range(d * d):
            for b in range(k):
                for j in range(d):
                    acc = 0.0
                    for l in range(d):
                        acc += dpdf[s, r, j * d + l] * grads[s, b, l]
                    tmp[s, r, b * d + j] = acc
        for a in range(k):
            for i in range(d):
                for c in range(n):
                    acc = 0.0
                    for m in range(d):
                        acc += grads[s, a, m] * tmp[s, i * d + m, c]
                    out[s, a * d + i, c] = volume[s] * acc
    return out
