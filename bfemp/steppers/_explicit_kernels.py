"""numba kernels of the explicit engine: one fused, parallel, race-free P2G with internal forces.

Per particle p with stencil nodes i (weights w_ip, gradients grad w_ip at x_p^n):

    m_i   += w_ip m_p
    m_i v_i += w_ip m_p (v_p + C_p (x_i - x_p))           (APIC; PIC and FLIP without C_p)
    f_i   -= V_p^0 P(F_p^n) (F_p^n)^T grad w_ip            (= -dPsi/dx_i at x^n, MPM eq. 25)

Race-freedom without atomics: the particles are cut into ``n_chunks`` contiguous ranges; chunk c
writes only into its own slab of a scratch buffer, which covers the node-index range
[lo_c, hi_c] its particles touch. Particles sampled lattice-wise (``bfemp.sample``) touch a short
node range per chunk (active nodes are sorted lexicographically), so the slabs together hold a
few times the grid (at most ``SLAB_BUDGET`` times: a scattered particle order halves the
number of chunks until it fits); a final parallel pass sums, for each node, the slabs that
cover it, in chunk order. The sums therefore depend on the particle order and on ``n_chunks``
only, never on the thread count or scheduling (results are bit-for-bit reproducible).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

#: the slabs may hold at most this many times the grid; fewer chunks are taken beyond it
SLAB_BUDGET = 4


@njit(cache=True, parallel=True)
def _chunk_ranges(nodes: np.ndarray, n_chunks: int) -> tuple[np.ndarray, np.ndarray]:
    """Smallest and largest node index ``lo (C,)``, ``hi (C,)`` touched by each chunk."""
    n_p, k = nodes.shape
    lo = np.empty(n_chunks, dtype=np.int64)
    hi = np.empty(n_chunks, dtype=np.int64)
    for c in prange(n_chunks):
        a = c * n_p // n_chunks
        b = (c + 1) * n_p // n_chunks
        mn = np.int64(1) << 62
        mx = np.int64(-1)
        for p in range(a, b):
            for s in range(k):
                i = nodes[p, s]
                if i < mn:
                    mn = i
                if i > mx:
                    mx = i
        if mx < 0:  # empty chunk
            mn = 0
        lo[c] = mn
        hi[c] = mx
    return lo, hi


@njit(cache=True, parallel=True)
def _p2g_force(
    nodes: np.ndarray,
    weights: np.ndarray,
    grads: np.ndarray,
    grid_x: np.ndarray,
    mpm_x: np.ndarray,
    mpm_mass: np.ndarray,
    mpm_v: np.ndarray,
    mpm_C: np.ndarray,
    affine: bool,
    piola: np.ndarray,
    mpm_F: np.ndarray,
    volume: np.ndarray,
    lo: np.ndarray,
    offset: np.ndarray,
    scratch: np.ndarray,
) -> None:
    """Scatter mass, momentum and internal force of every chunk into its slab of ``scratch``.

    ``scratch (sum_c (hi_c - lo_c + 1), 1 + 2 d)`` zeroed; row ``offset[c] + i - lo[c]`` holds
    chunk c's [m_i, (m v)_i (d), f_i (d)].
    """
    n_p, k = nodes.shape
    d = grid_x.shape[1]
    n_chunks = lo.shape[0]
    for c in prange(n_chunks):
        base = offset[c] - lo[c]
        tau = np.empty((d, d))
        for p in range(c * n_p // n_chunks, (c + 1) * n_p // n_chunks):
            # tau = V_p^0 P F^T (the Kirchhoff stress times the rest volume)
            for r in range(d):
                for s in range(d):
                    acc = 0.0
                    for m in range(d):
                        acc += piola[p, r, m] * mpm_F[p, s, m]
                    tau[r, s] = volume[p] * acc
            mp = mpm_mass[p]
            for a in range(k):
                i = nodes[p, a]
                row = base + i
                wm = weights[p, a] * mp
                scratch[row, 0] += wm
                for r in range(d):
                    v = mpm_v[p, r]
                    if affine:
                        for s in range(d):
                            v += mpm_C[p, r, s] * (grid_x[i, s] - mpm_x[p, s])
                    scratch[row, 1 + r] += wm * v
                    f = 0.0
                    for s in range(d):
                        f += tau[r, s] * grads[p, a, s]
                    scratch[row, 1 + d + r] -= f


@njit(cache=True, parallel=True)
def _reduce_slabs(
    scratch: np.ndarray, lo: np.ndarray, hi: np.ndarray, offset: np.ndarray, out: np.ndarray
) -> None:
    """out (G, 1 + 2 d) = sum over chunks c covering node i of their slab rows (chunk order)."""
    n_grid, width = out.shape
    n_chunks = lo.shape[0]
    for i in prange(n_grid):
        for j in range(width):
            out[i, j] = 0.0
        for c in range(n_chunks):
            if lo[c] <= i and i <= hi[c]:
                row = offset[c] + i - lo[c]
                for j in range(width):
                    out[i, j] += scratch[row, j]


def p2g_with_forces(
    nodes: np.ndarray,
    weights: np.ndarray,
    grads: np.ndarray,
    grid_x: np.ndarray,
    mpm_x: np.ndarray,
    mpm_mass: np.ndarray,
    mpm_v: np.ndarray,
    mpm_C: np.ndarray | None,
    piola: np.ndarray,
    mpm_F: np.ndarray,
    volume: np.ndarray,
    n_chunks: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Grid mass ``(G,)`` kg, momentum ``(G, d)`` kg m/s and internal force ``(G, d)`` N.

    Args:
        nodes, weights, grads: particle stencils ``(P, K)``, ``(P, K)``, ``(P, K, d)`` (1/m).
        grid_x: active node positions ``(G, d)`` in m.
        mpm_x, mpm_mass, mpm_v: particle positions (m), masses (kg), velocities (m/s).
        mpm_C: APIC affine velocities ``(P, d, d)`` in 1/s, or None (PIC, FLIP).
        piola: first Piola stresses P(F_p^n) ``(P, d, d)`` in Pa.
        mpm_F: deformation gradients F_p^n ``(P, d, d)``.
        volume: rest volumes V_p^0 ``(P,)`` in m^d.
        n_chunks: number of particle ranges scattered in parallel (see the module docstring).
    """
    n_grid, d = grid_x.shape
    n_p = nodes.shape[0]
    n_chunks = max(1, min(int(n_chunks), n_p))
    lo, hi = _chunk_ranges(nodes, n_chunks)
    sizes = np.maximum(hi - lo + 1, 0)
    while n_chunks > 1 and sizes.sum() > SLAB_BUDGET * n_grid:  # scattered particle order
        n_chunks //= 2
        lo, hi = _chunk_ranges(nodes, n_chunks)
        sizes = np.maximum(hi - lo + 1, 0)
    offset = np.zeros(n_chunks, dtype=np.int64)
    offset[1:] = np.cumsum(sizes)[:-1]
    scratch = np.zeros((int(sizes.sum()), 1 + 2 * d))
    affine = mpm_C is not None
    C = mpm_C if affine else np.zeros((0, d, d))
    _p2g_force(
        nodes, weights, grads, grid_x, mpm_x, mpm_mass, mpm_v, C, affine, piola, mpm_F, volume,
        lo, offset, scratch,
    )  # fmt: skip
    out = np.empty((n_grid, 1 + 2 * d))
    _reduce_slabs(scratch, lo, hi, offset, out)
    return out[:, 0].copy(), out[:, 1 : 1 + d].copy(), out[:, 1 + d :].copy()
