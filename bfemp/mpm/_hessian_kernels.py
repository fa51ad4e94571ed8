"""numba kernels that accumulate MPM particle Hessians into the grid's node-pair pattern.

Two stencil entries a, b of one particle sit at the node offsets o_a, o_b in {0, 1, 2}^d from the
particle's base node, so their relative offset o_b - o_a lies in {-2, ..., 2}^d: each grid node
couples with at most 5^d nodes. Blocks are stored per (node, relative offset) - (G, 5^d, d, d) -
so no (3^d d)^2 per-particle block list is ever materialised.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True)
def _neighbour_table(nodes, weights, grads, pair_code, n_nodes, n_codes):  # noqa: ANN001, ANN202
    """nbr (G, 5^d): the node at each relative offset of node i, -1 where no particle couples."""
    nbr = np.full((n_nodes, n_codes), -1, dtype=np.int64)
    n_p, k = nodes.shape
    d = grads.shape[2]
    for p in range(n_p):
        for a in range(k):
            if _is_void(weights, grads, p, a, d):
                continue
            for b in range(k):
                if _is_void(weights, grads, p, b, d):
                    continue
                nbr[nodes[p, a], pair_code[a, b]] = nodes[p, b]
    return nbr


@njit(cache=True, inline="always")
def _is_void(weights, grads, p, a, d):  # noqa: ANN001, ANN202
    """Entries with zero weight and zero gradient (redirected by geometry.grid) contribute 0."""
    if weights[p, a] != 0.0:
        return False
    for c in range(d):
        if grads[p, a, c] != 0.0:
            return False
    return True


def _accumulate_blocks(
    nodes: np.ndarray,
    weights: np.ndarray,
    grads: np.ndarray,
    dpdf: np.ndarray,
    volume: np.ndarray,
    pair_code: np.ndarray,
    nbr: np.ndarray,
    n_nodes: int,
    n_codes: int,
    n_chunks: int,
) -> np.ndarray:
    """blocks (G, 5^d, d, d): sum_p V_p g_a^T dP g_b (d x d per node pair; F-level PSD input).

    ``dpdf`` is (S, d*d, d*d) with dP_im/dF_jl at [i*d + m, j*d + l]; ``grads`` are the effective
    gradients g (P, K, d) with F = sum_a y_a g_a^T; ``dpdf`` must be symmetric (a Hessian in F,
    projected or not): half the node pairs are accumulated, the other half mirrored through the
    neighbour table ``nbr`` (G, 5^d). Particles are split into ``n_chunks`` ranges
    accumulated in parallel into private copies (race-free), then summed.

    The kernel is compiled once per dimension with d a constant, so numba unrolls the d-loops
    (about 2.5x faster in 2D than a kernel reading d from the array shape).
    """
    kernel = {2: _accumulate_blocks_2d, 3: _accumulate_blocks_3d}.get(grads.shape[2])
    if kernel is None:
        raise ValueError(f"grads must be (P, K, 2) or (P, K, 3), got {grads.shape}")
    return kernel(nodes, weights, grads, dpdf, volume, pair_code, nbr, n_nodes, n_codes, n_chunks)


def _dim_kernel(dim: int):  # noqa: ANN202
    """The parallel body of _accumulate_blocks, compiled with ``dim`` a constant (closure).
    The closure holds ``dim`` only: numba keys a closure's cache entry by its pickled cells, and
    a pickled kernel differs in every process (then every process compiled it: 3 s in 2D, 8 s
    in 3D). The branches on ``dim`` fold at compile time."""

    @njit(cache=True, parallel=True)
    def kernel(
        nodes,  # noqa: ANN001
        weights,  # noqa: ANN001
        grads,  # noqa: ANN001
        dpdf,  # noqa: ANN001
        volume,  # noqa: ANN001
        pair_code,  # noqa: ANN001
        nbr,  # noqa: ANN001
        n_nodes,  # noqa: ANN001
        n_codes,  # noqa: ANN001
        n_chunks,  # noqa: ANN001
    ):  # noqa: ANN202
        n_p, k = nodes.shape
        centre = (n_codes - 1) // 2  # the code of offset 0; code(-o) = n_codes - 1 - code(o)
        partial = np.zeros((n_chunks, n_nodes, n_codes, dim, dim))
        for c in prange(n_chunks):
            blocks = partial[c]
            tmp = np.empty((k, dim, dim, dim))
            void = np.empty(k, dtype=np.bool_)
            for p in range(c * n_p // n_chunks, (c + 1) * n_p // n_chunks):
                for b in range(k):
                    void[b] = _is_void(weights, grads, p, b, dim)
                    if dim == 2:
                        _contract_2d(dpdf, grads, volume, p, b, tmp)
                    else:
                        _contract_3d(dpdf, grads, volume, p, b, tmp)
                for a in range(k):
                    if void[a]:
                        continue
                    for b in range(k):
                        code = pair_code[a, b]
                        # dP is symmetric, so block (b, a) = block (a, b)^T: only offsets with
                        # code >= centre are accumulated here, the others by _mirror_blocks
                        if code >= centre and not void[b]:
                            if dim == 2:
                                _add_block_2d(grads, p, a, tmp, b, blocks, nodes[p, a], code)
                            else:
                                _add_block_3d(grads, p, a, tmp, b, blocks, nodes[p, a], code)
        out = partial[0]
        for c in range(1, n_chunks):
            out += partial[c]
        _mirror_blocks(out, nbr)
        return out

    return kernel


# The per-entry pieces of the kernel, one per dimension, written out in scalars: every load of
# a pair comes before its stores. In loops over d, numba reloaded the gradients and tmp after
# each store into ``blocks`` (it cannot rule out aliasing), and those loads stalled on the
# stores where the arrays' addresses shared their low 12 bits ("4K aliasing"): the 3D kernel
# took 0.24 s against 0.16 s at the twist's 110,592 particles, with the same sums in the same
# order (bit for bit).


@njit(cache=True, inline="always")
def _contract_3d(dpdf, grads, volume, p, b, tmp):  # noqa: ANN001, ANN202
    """tmp[b, i, m, j] = V_p sum_l dpdf[p, (i, m), (j, l)] g_b[l] (l in increasing order)."""
    v = volume[p]
    g0 = grads[p, b, 0]
    g1 = grads[p, b, 1]
    g2 = grads[p, b, 2]
    for i in range(3):
        for m in range(3):
            r = 3 * i + m
            for j in range(3):
                tmp[b, i, m, j] = v * (
                    0.0
                    + dpdf[p, r, 3 * j] * g0
                    + dpdf[p, r, 3 * j + 1] * g1
                    + dpdf[p, r, 3 * j + 2] * g2
                )


@njit(cache=True, inline="always")
def _contract_2d(dpdf, grads, volume, p, b, tmp):  # noqa: ANN001, ANN202
    """``_contract_3d`` in 2D."""
    v = volume[p]
    g0 = grads[p, b, 0]
    g1 = grads[p, b, 1]
    for i in range(2):
        for m in range(2):
            r = 2 * i + m
            for j in range(2):
                tmp[b, i, m, j] = v * (0.0 + dpdf[p, r, 2 * j] * g0 + dpdf[p, r, 2 * j + 1] * g1)


@njit(cache=True, inline="always")
def _add_block_3d(grads, p, a, tmp, b, blocks, node, code):  # noqa: ANN001, ANN202
    """blocks[node, code, i, j] += sum_m g_a[m] tmp[b, i, m, j] (m in increasing order), all
    loads first."""
    g0 = grads[p, a, 0]
    g1 = grads[p, a, 1]
    g2 = grads[p, a, 2]
    s00 = 0.0 + g0 * tmp[b, 0, 0, 0] + g1 * tmp[b, 0, 1, 0] + g2 * tmp[b, 0, 2, 0]
    s01 = 0.0 + g0 * tmp[b, 0, 0, 1] + g1 * tmp[b, 0, 1, 1] + g2 * tmp[b, 0, 2, 1]
    s02 = 0.0 + g0 * tmp[b, 0, 0, 2] + g1 * tmp[b, 0, 1, 2] + g2 * tmp[b, 0, 2, 2]
    s10 = 0.0 + g0 * tmp[b, 1, 0, 0] + g1 * tmp[b, 1, 1, 0] + g2 * tmp[b, 1, 2, 0]
    s11 = 0.0 + g0 * tmp[b, 1, 0, 1] + g1 * tmp[b, 1, 1, 1] + g2 * tmp[b, 1, 2, 1]
    s12 = 0.0 + g0 * tmp[b, 1, 0, 2] + g1 * tmp[b, 1, 1, 2] + g2 * tmp[b, 1, 2, 2]
    s20 = 0.0 + g0 * tmp[b, 2, 0, 0] + g1 * tmp[b, 2, 1, 0] + g2 * tmp[b, 2, 2, 0]
    s21 = 0.0 + g0 * tmp[b, 2, 0, 1] + g1 * tmp[b, 2, 1, 1] + g2 * tmp[b, 2, 2, 1]
    s22 = 0.0 + g0 * tmp[b, 2, 0, 2] + g1 * tmp[b, 2, 1, 2] + g2 * tmp[b, 2, 2, 2]
    blocks[node, code, 0, 0] += s00
    blocks[node, code, 0, 1] += s01
    blocks[node, code, 0, 2] += s02
    blocks[node, code, 1, 0] += s10
    blocks[node, code, 1, 1] += s11
    blocks[node, code, 1, 2] += s12
    blocks[node, code, 2, 0] += s20
    blocks[node, code, 2, 1] += s21
    blocks[node, code, 2, 2] += s22


@njit(cache=True, inline="always")
def _add_block_2d(grads, p, a, tmp, b, blocks, node, code):  # noqa: ANN001, ANN202
    """``_add_block_3d`` in 2D."""
    g0 = grads[p, a, 0]
    g1 = grads[p, a, 1]
    s00 = 0.0 + g0 * tmp[b, 0, 0, 0] + g1 * tmp[b, 0, 1, 0]
    s01 = 0.0 + g0 * tmp[b, 0, 0, 1] + g1 * tmp[b, 0, 1, 1]
    s10 = 0.0 + g0 * tmp[b, 1, 0, 0] + g1 * tmp[b, 1, 1, 0]
    s11 = 0.0 + g0 * tmp[b, 1, 0, 1] + g1 * tmp[b, 1, 1, 1]
    blocks[node, code, 0, 0] += s00
    blocks[node, code, 0, 1] += s01
    blocks[node, code, 1, 0] += s10
    blocks[node, code, 1, 1] += s11


_accumulate_blocks_2d = _dim_kernel(2)
_accumulate_blocks_3d = _dim_kernel(3)


@njit(cache=True)
def _mirror_blocks(blocks, nbr):  # noqa: ANN001, ANN202
    """blocks[j, code(-o)] = blocks[i, code(o)]^T for j = nbr[i, code(o)], code(o) > centre."""
    n_nodes, n_codes, d, _ = blocks.shape
    centre = (n_codes - 1) // 2
    for i in range(n_nodes):
        for code in range(centre + 1, n_codes):
            j = nbr[i, code]
            if j < 0:
                continue
            back = n_codes - 1 - code
            for r in range(d):
                for s in range(d):
                    blocks[j, back, r, s] = blocks[i, code, s, r]


@njit(cache=True, parallel=True)
def _effective_gradients(F_n, grads_w, nodes, active_x, particles):  # noqa: ANN001, ANN202
    """g (p, K, d) and C (p, d, d) of the selected particles (BFEMP eq. 25 made affine).

    ``g_pk = (F_p^n)^T grad w_pk`` and ``C_p = F_p^n - sum_k x_k^n g_pk^T`` for p in
    ``particles`` (p,), from ``F_n`` (P, d, d), ``grads_w`` (P, K, d) in 1/m, ``nodes`` (P, K)
    into ``active_x`` (G, d) in m; the sums run over j and k in increasing order, as the
    ``np.einsum`` calls they replace do.
    """
    n_sel = particles.size
    k_st, d = grads_w.shape[1], grads_w.shape[2]
    g = np.empty((n_sel, k_st, d))
    const = np.empty((n_sel, d, d))
    for s in prange(n_sel):
        p = particles[s]
        for k in range(k_st):
            for i in range(d):
                acc = 0.0
                for j in range(d):
                    acc += F_n[p, j, i] * grads_w[p, k, j]
                g[s, k, i] = acc
        for i in range(d):
            for j in range(d):
                acc = 0.0
                for k in range(k_st):
                    acc += active_x[nodes[p, k], i] * g[s, k, j]
                const[s, i, j] = F_n[p, i, j] - acc
    return g, const


@njit(cache=True)
def _pair_pattern(nbr, dof_grid, d):  # noqa: ANN001, ANN202
    """Rows, columns and kept block entries of the node-pair blocks (G, 5^d, d, d).

    Entry ``(i, code, r, s)`` of the blocks couples DOF ``dof(i) d + r`` with ``dof(j) d + s``
    for ``j = nbr[i, code]``; it is kept where both nodes are unknowns (``dof_grid`` (G,) >= 0;
    -1: prescribed or sticky) and ``j >= 0``. Returns ``rows, cols`` (n,) int64 of the kept
    entries, in the row-major order of the blocks, and ``keep`` (G 5^d d d,) bool.
    """
    n_nodes, n_codes = nbr.shape
    keep = np.zeros(n_nodes * n_codes * d * d, dtype=np.bool_)
    n = 0
    for i in range(n_nodes):
        if dof_grid[i] < 0:
            continue
        for code in range(n_codes):
            j = nbr[i, code]
            if j >= 0 and dof_grid[j] >= 0:
                n += 1
    rows = np.empty(n * d * d, dtype=np.int64)
    cols = np.empty(n * d * d, dtype=np.int64)
    q = 0
    for i in range(n_nodes):
        di = dof_grid[i]
        if di < 0:
            continue
        for code in range(n_codes):
            j = nbr[i, code]
            if j < 0 or dof_grid[j] < 0:
                continue
            dj = dof_grid[j]
            base = (i * n_codes + code) * d * d
            for r in range(d):
                for s in range(d):
                    keep[base + r * d + s] = True
                    rows[q] = di * d + r
                    cols[q] = dj * d + s
                    q += 1
    return rows, cols, keep
