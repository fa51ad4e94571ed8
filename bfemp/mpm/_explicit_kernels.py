"""numba kernels of the explicit engine: one fused, parallel, race-free P2G with internal forces.

Per particle p with stencil nodes i (weights w_ip, gradients grad w_ip at x_p^n):

    m_i   += w_ip m_p
    m_i v_i += w_ip m_p (v_p + C_p (x_i - x_p))           (APIC; PIC and FLIP without C_p)
    f_i   -= V_p^0 P(F_p^n) (F_p^n)^T grad w_ip            (= -dPsi/dx_i at x^n, BFEMP eq. 25)

Race-freedom without atomics: the particles are cut into ``n_chunks`` contiguous ranges; chunk c
writes only into its own slab of a scratch buffer, which covers the node-index range
[lo_c, hi_c] its particles touch. Particles sampled lattice-wise (``bfemp.sample``) touch a short
node range per chunk (active nodes are sorted lexicographically), so the slabs together hold a
few times the grid (at most ``SLAB_BUDGET`` times: a scattered particle order halves the
number of chunks until it fits); a final serial pass adds the slabs into the grid in chunk
order. The sums therefore depend on the particle order and on ``n_chunks``
only, never on the thread count or scheduling (results are bit-for-bit reproducible).

Why a fused P2G kernel rather than the terms for MPM: ``MpmElasticityTerm.begin_step`` builds the
node-pair pattern of the Hessian (a serial neighbour table and (G 5^d d^2) row/column arrays)
that an explicit step never uses, and the base ``ElasticityTerm`` route would build the
(3^d d)^2-per-particle block pattern; the fused kernel reads every stencil once for mass,
momentum and force, a few per cent of the term route's time (design note ``measurements``,
mpm). FEM cells keep the term (fixed stencils, pattern built once).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numba import njit, prange

from bfemp.mpm._transfer_kernels import (
    _affine_matrix,
    _affine_value,
    _deformation_update,
    _gathered,
    _kirchhoff_volume,
)

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
            _kirchhoff_volume(piola, mpm_F, volume, p, tau)
            mp = mpm_mass[p]
            for a in range(k):
                i = nodes[p, a]
                row = base + i
                wm = weights[p, a] * mp
                scratch[row, 0] += wm
                for r in range(d):
                    v = _affine_value(mpm_v, mpm_C, affine, p, r, grid_x, i, mpm_x)
                    scratch[row, 1 + r] += wm * v
                    f = 0.0
                    for s in range(d):
                        f += tau[r, s] * grads[p, a, s]
                    scratch[row, 1 + d + r] -= f


@njit(cache=True)
def _reduce_slabs(
    scratch: np.ndarray, lo: np.ndarray, hi: np.ndarray, offset: np.ndarray, out: np.ndarray
) -> None:
    """out (G, 1 + 2 d) = the sum of the chunks' slabs, added in chunk order (deterministic).

    Serial: the slabs hold a few times G rows, so this is a few G vector adds (a parallel pass
    over nodes that tests every chunk's range cost G x n_chunks tests).
    """
    width = out.shape[1]
    out[:] = 0.0
    for c in range(lo.shape[0]):
        if hi[c] < lo[c]:
            continue
        for r in range(hi[c] - lo[c] + 1):
            src = offset[c] + r
            dst = lo[c] + r
            for j in range(width):
                out[dst, j] += scratch[src, j]


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
        nodes,
        weights,
        grads,
        grid_x,
        mpm_x,
        mpm_mass,
        mpm_v,
        C,
        affine,
        piola,
        mpm_F,
        volume,
        lo,
        offset,
        scratch,
    )
    out = np.empty((n_grid, 1 + 2 * d))
    _reduce_slabs(scratch, lo, hi, offset, out)
    return out[:, 0].copy(), out[:, 1 : 1 + d].copy(), out[:, 1 + d :].copy()


@njit(cache=True, parallel=True)
def _g2p_explicit(
    nodes: np.ndarray,
    weights: np.ndarray,
    grads: np.ndarray,
    grid_x: np.ndarray,
    grid_v_old: np.ndarray,
    grid_v: np.ndarray,
    dt: float,
    mpm_x: np.ndarray,
    mpm_v: np.ndarray,
    mpm_F: np.ndarray,
    flip: bool,
    apic: bool,
    n_chunks: int,
    out_x: np.ndarray,
    out_v: np.ndarray,
    out_F: np.ndarray,
    out_C: np.ndarray,
    singular: np.ndarray,
) -> None:
    """G2P of ``grid_to_particles`` with x~_i = x_i + dt v_i, allocation-free per particle.

    x_p = sum_i w x~_i; F_p = (sum_i x~_i grad w^T) F_p^n; v_p = sum_i w v_i (PIC, APIC) or
    v_p^n + sum_i w (v_i - v_i^n) (FLIP); APIC: C_p = B_p D_p^-1 with the symmetrised B_p of
    Table 1 (a_i = x_i - x_p^n, b_i = x~_i - x_p^{n+1}). Each particle writes only its own rows;
    the d x d scratch matrices are per chunk (no heap allocation per particle).
    """
    n_p, k = nodes.shape
    d = grid_x.shape[1]
    for c in prange(n_chunks):
        G = np.empty((d, d))
        B = np.empty((d, d))
        D = np.empty((d, d))
        C = np.empty((d, d))
        xn = np.empty(d)
        for p in range(c * n_p // n_chunks, (c + 1) * n_p // n_chunks):
            for r in range(d):
                xn[r] = 0.0
                out_v[p, r] = mpm_v[p, r] if flip else 0.0
                for s in range(d):
                    G[r, s] = 0.0
            for a in range(k):
                i = nodes[p, a]
                w = weights[p, a]
                for r in range(d):
                    xr = grid_x[i, r] + dt * grid_v[i, r]
                    xn[r] += w * xr
                    out_v[p, r] += _gathered(w, grid_v, grid_v_old, i, r, flip)
                    for s in range(d):
                        G[r, s] += xr * grads[p, a, s]
            for r in range(d):
                out_x[p, r] = xn[r]
            _deformation_update(G, mpm_F, p, out_F)
            singular[p] = False
            if not apic:
                continue
            for r in range(d):
                for s in range(d):
                    B[r, s] = 0.0
                    D[r, s] = 0.0
            for a in range(k):
                i = nodes[p, a]
                w = weights[p, a]
                for r in range(d):
                    ar = grid_x[i, r] - mpm_x[p, r]
                    br = grid_x[i, r] + dt * grid_v[i, r] - xn[r]
                    vr = grid_v[i, r]
                    for s in range(d):
                        as_ = grid_x[i, s] - mpm_x[p, s]
                        bs = grid_x[i, s] + dt * grid_v[i, s] - xn[s]
                        B[r, s] += 0.5 * w * (vr * (as_ + bs) + (ar - br) * grid_v[i, s])
                        D[r, s] += w * ar * as_
            singular[p] = not _affine_matrix(D, B, C, out_C[p])


def g2p_explicit(
    scheme: str,
    nodes: np.ndarray,
    weights: np.ndarray,
    grads: np.ndarray,
    grid_x: np.ndarray,
    grid_v_old: np.ndarray,
    grid_v: np.ndarray,
    dt: float,
    mpm_x: np.ndarray,
    mpm_v: np.ndarray,
    mpm_F: np.ndarray,
    n_chunks: int,
    alloc: Callable[[tuple[int, ...]], np.ndarray] = np.empty,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(mpm_x, mpm_v, mpm_F, mpm_C)`` after G2P of the explicit step (see ``_g2p_explicit``).

    Args:
        scheme: ``"apic"``, ``"pic"`` or ``"flip"``.
        nodes, weights, grads: stencils at x_p^n ``(P, K)``, ``(P, K)``, ``(P, K, d)`` (1/m).
        grid_x: node positions x_i^n ``(G, d)`` in m.
        grid_v_old: P2G velocities v_i^n ``(G, d)`` in m/s (FLIP).
        grid_v: end velocities v_i ``(G, d)`` in m/s.
        dt: time step in s.
        mpm_x, mpm_v, mpm_F: particle state at t^n.
        n_chunks: particle ranges processed in parallel.
        alloc: ``alloc(shape)`` gives the output arrays (``BufferPool.empty``).
    """
    n_p, d = mpm_x.shape
    out_x = alloc((n_p, d))
    out_v = alloc((n_p, d))
    out_F = alloc((n_p, d, d))
    out_C = alloc((n_p, d, d))
    out_C.fill(0.0)
    singular = np.zeros(n_p, dtype=np.bool_)
    _g2p_explicit(
        nodes,
        weights,
        grads,
        grid_x,
        grid_v_old,
        grid_v,
        float(dt),
        mpm_x,
        mpm_v,
        mpm_F,
        scheme == "flip",
        scheme == "apic",
        max(1, min(int(n_chunks), n_p)),
        out_x,
        out_v,
        out_F,
        out_C,
        singular,
    )
    if singular.any():
        raise ValueError(
            "APIC inertia D_p = sum_i w_ip (x_i - x_p)(x_i - x_p)^T is singular at particles "
            f"{np.flatnonzero(singular)[:10]} (degenerate stencil weights)"
        )
    return out_x, out_v, out_F, out_C
