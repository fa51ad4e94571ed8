"""numba kernels of the elasticity term: F from stencils, force scatter, local Hessians.

A stencil s has k nodes; its deformation gradient is affine in their positions y (m):
    F_s = C_s + sum_a y_{n(s,a)} g_{s,a}^T,
with g (1/m) the shape-function gradients (FEM, BFEMP eq. 24) or F^n-weighted B-spline gradients
(MPM).

Each kernel is compiled once per dimension with d a constant (a generic body marked
``inline="always"`` and thin 2D / 3D wrappers), so numba unrolls the d-loops; the public names
are Python dispatchers on the array shapes. The same treatment made the MPM Hessian
accumulation 2.7x faster (``bfemp.mpm._hessian_kernels``).
"""

from __future__ import annotations

import numba
import numpy as np
from numba import njit, prange


def _pick(kernels: tuple, d: int, what: str, shape: tuple) -> object:
    """The 2D or 3D compiled kernel of ``kernels`` for dimension ``d``; ValueError otherwise."""
    if d == 2:
        return kernels[0]
    if d == 3:
        return kernels[1]
    raise ValueError(f"{what} must have d = 2 or 3 in its last axis, got shape {shape}")


def _chunks(n: int) -> int:
    """Private copies for a parallel scatter over ``n`` stencils: one per thread, >= 256 each."""
    return max(1, min(numba.get_num_threads(), n // 256))


# ------------------------------------------------------------------------ F = C + sum y g^T
def _deformation_gradients(
    y: np.ndarray, nodes: np.ndarray, grads: np.ndarray, const: np.ndarray
) -> np.ndarray:
    """F (S, d, d) = const + sum_a outer(y[nodes[s, a]], grads[s, a]).

    Args:
        y: node positions (n_nodes, d) in m (or a direction, with ``const`` zero).
        nodes: (S, k) node of each stencil entry.
        grads: (S, k, d) gradients g in 1/m.
        const: (S, d, d) the constant part C.
    """
    kernel = _pick(_deformation_gradients_k, y.shape[1], "y", y.shape)
    return kernel(y, nodes, grads, const)


@njit(inline="always")
def _deformation_gradients_impl(dim, y, nodes, grads, const):  # noqa: ANN001, ANN202
    n_s, k = nodes.shape
    out = np.empty((n_s, dim, dim))
    for s in prange(n_s):
        for i in range(dim):
            for j in range(dim):
                out[s, i, j] = const[s, i, j]
        for a in range(k):
            node = nodes[s, a]
            for i in range(dim):
                yi = y[node, i]
                for j in range(dim):
                    out[s, i, j] += yi * grads[s, a, j]
    return out


@njit(cache=True, parallel=True)
def _deformation_gradients_2d(y, nodes, grads, const):  # noqa: ANN001, ANN202
    return _deformation_gradients_impl(2, y, nodes, grads, const)


@njit(cache=True, parallel=True)
def _deformation_gradients_3d(y, nodes, grads, const):  # noqa: ANN001, ANN202
    return _deformation_gradients_impl(3, y, nodes, grads, const)


_deformation_gradients_k = (_deformation_gradients_2d, _deformation_gradients_3d)


# ------------------------------------------------------------------------ forces
def _scatter_forces(
    out: np.ndarray, nodes: np.ndarray, grads: np.ndarray, stress_volume: np.ndarray
) -> None:
    """out[nodes[s, a]] += (V P)_s g_{s, a}: dPsi/dy by the chain rule dF/dy_a = (.) g_a^T.

    Args:
        out: (n_nodes, d) forces in N, added to in place.
        nodes: (S, k); grads: (S, k, d) in 1/m; stress_volume: (S, d, d) V P in N m.

    Stencils are split into ranges scattered in parallel into private copies, then summed.
    """
    kernel = _pick(_scatter_forces_k, out.shape[1], "out", out.shape)
    kernel(out, nodes, grads, stress_volume, _chunks(nodes.shape[0]))


@njit(inline="always")
def _scatter_forces_impl(dim, out, nodes, grads, stress_volume, n_chunks):  # noqa: ANN001, ANN202
    n_s, k = nodes.shape
    partial = np.zeros((n_chunks, out.shape[0], dim))
    for c in prange(n_chunks):
        mine = partial[c]
        for s in range(c * n_s // n_chunks, (c + 1) * n_s // n_chunks):
            for a in range(k):
                node = nodes[s, a]
                for i in range(dim):
                    acc = 0.0
                    for j in range(dim):
                        acc += stress_volume[s, i, j] * grads[s, a, j]
                    mine[node, i] += acc
    for c in range(n_chunks):
        out += partial[c]


@njit(cache=True, parallel=True)
def _scatter_forces_2d(out, nodes, grads, stress_volume, n_chunks):  # noqa: ANN001, ANN202
    _scatter_forces_impl(2, out, nodes, grads, stress_volume, n_chunks)


@njit(cache=True, parallel=True)
def _scatter_forces_3d(out, nodes, grads, stress_volume, n_chunks):  # noqa: ANN001, ANN202
    _scatter_forces_impl(3, out, nodes, grads, stress_volume, n_chunks)


_scatter_forces_k = (_scatter_forces_2d, _scatter_forces_3d)


# ------------------------------------------------------------------------ local Hessians
def _local_hessians(dpdf: np.ndarray, grads: np.ndarray, volume: np.ndarray) -> np.ndarray:
    """H (S, k d, k d): H[a d + i, b d + j] = V sum_{m, l} dP_{i m, j l} g_{a m} g_{b l}.

    ``dpdf`` is (S, d*d, d*d) with row index i*d + m and column index j*d + l (dP_im / dF_jl);
    ``grads`` (S, k, d) in 1/m; ``volume`` (S,) in m^3 (m^2 in 2D).
    """
    kernel = _pick(_local_hessians_k, grads.shape[2], "grads", grads.shape)
    return kernel(dpdf, grads, volume)


@njit(inline="always")
def _local_hessians_impl(dim, dpdf, grads, volume):  # noqa: ANN001, ANN202
    n_s, k, _ = grads.shape
    n = k * dim
    out = np.empty((n_s, n, n))
    tmp = np.empty((n_s, dim * dim, n))  # dP . (e_j g_b^T): contract the column side first
    for s in prange(n_s):
        for r in range(dim * dim):
            for b in range(k):
                for j in range(dim):
                    acc = 0.0
                    for l in range(dim):
                        acc += dpdf[s, r, j * dim + l] * grads[s, b, l]
                    tmp[s, r, b * dim + j] = acc
        v = volume[s]
        for a in range(k):
            for i in range(dim):
                for c in range(n):
                    acc = 0.0
                    for m in range(dim):
                        acc += grads[s, a, m] * tmp[s, i * dim + m, c]
                    out[s, a * dim + i, c] = v * acc
    return out


@njit(cache=True, parallel=True)
def _local_hessians_2d(dpdf, grads, volume):  # noqa: ANN001, ANN202
    return _local_hessians_impl(2, dpdf, grads, volume)


@njit(cache=True, parallel=True)
def _local_hessians_3d(dpdf, grads, volume):  # noqa: ANN001, ANN202
    return _local_hessians_impl(3, dpdf, grads, volume)


_local_hessians_k = (_local_hessians_2d, _local_hessians_3d)
