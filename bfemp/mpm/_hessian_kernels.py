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


@njit(cache=True, parallel=True)
def _accumulate_blocks(  # noqa: ANN202
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
):
    """blocks (G, 5^d, d, d): sum_p V_p g_a^T dP g_b (d x d per node pair; F-level PSD input).

    ``dpdf`` is (S, d*d, d*d) with dP_im/dF_jl at [i*d + m, j*d + l]; ``grads`` are the effective
    gradients g (P, K, d) with F = sum_a y_a g_a^T; ``dpdf`` must be symmetric (a Hessian in F,
    projected or not): half the node pairs are accumulated, the other half mirrored through the
    neighbour table ``nbr`` (G, 5^d). Particles are split into ``n_chunks`` ranges
    accumulated in parallel into private copies (race-free), then summed.
    """
    n_p, k = nodes.shape
    d = grads.shape[2]
    centre = (n_codes - 1) // 2  # the code of offset 0; code(-o) = n_codes - 1 - code(o)
    partial = np.zeros((n_chunks, n_nodes, n_codes, d, d))
    for c in prange(n_chunks):
        blocks = partial[c]
        tmp = np.empty((d * d, k * d))
        for p in range(c * n_p // n_chunks, (c + 1) * n_p // n_chunks):
            # tmp[(i, m), (b, j)] = sum_l dP[(i, m), (j, l)] g_b[l]
            for r in range(d * d):
                for b in range(k):
                    for j in range(d):
                        acc = 0.0
                        for l in range(d):
                            acc += dpdf[p, r, j * d + l] * grads[p, b, l]
                        tmp[r, b * d + j] = acc
            for a in range(k):
                if _is_void(weights, grads, p, a, d):
                    continue
                node_a = nodes[p, a]
                for b in range(k):
                    code = pair_code[a, b]
                    # dP is symmetric, so block (b, a) = block (a, b)^T: only offsets with
                    # code >= centre are accumulated here, the others by _mirror_blocks
                    if code < centre or _is_void(weights, grads, p, b, d):
                        continue
                    for i in range(d):
                        for j in range(d):
                            acc = 0.0
                            for m in range(d):
                                acc += grads[p, a, m] * tmp[i * d + m, b * d + j]
                            blocks[node_a, code, i, j] += volume[p] * acc
    out = partial[0].copy()
    for c in range(1, n_chunks):
        out += partial[c]
    _mirror_blocks(out, nbr)
    return out


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
