"""numba kernels: chain rule from collision points (affine images of nodes) to node DOFs.

A pair has m collision points; point c sits at sum_k w[c, k] y[nodes[c, k]]. Local derivatives with
respect to the m points (m d entries) map to nodes by the weights (BFEMP eq. 29): gradient rows
scale by w, Hessian blocks (a, b) by w_a w_b. Zero weights (padding, redirected B-spline entries)
and prescribed nodes are skipped, and the blocks of all pairs that land on one (node, node) pair
are summed here, so the triplets hold each coupled node pair once.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _scatter_gradient(out, local, pair_points, nodes, weights):  # noqa: ANN001, ANN202
    """out[node] += w * local[pair, a] for every point a of every pair (out: (n_all, d))."""
    n, m = pair_points.shape
    k = nodes.shape[1]
    d = out.shape[1]
    for p in range(n):
        for a in range(m):
            c = pair_points[p, a]
            for j in range(k):
                w = weights[c, j]
                if w == 0.0:
                    continue
                node = nodes[c, j]
                for i in range(d):
                    out[node, i] += w * local[p, a * d + i]


@njit(cache=True)
def _chain_hessian(hess, pair_points, nodes, weights, dof_node):  # noqa: ANN001, ANN202
    """Node-level Hessian sum_pairs W_p^T hess_p W_p as triplets with unique (row, column) blocks.

    ``hess (n, m d, m d)`` symmetric local Hessians; ``pair_points (n, m)``; ``nodes, weights
    (C, k)`` the collision map; ``dof_node (n_all,)`` free-node index (its DOFs are
    ``d dn .. d dn + d - 1``) or -1. The (free node, free node) blocks of all pairs are summed
    here, by Gustavson's row-wise sparse product: row node by row node, the entries of the pairs
    whose stencils hold it are visited and a marker per column node finds their block in the
    row. So the output holds one d x d block per coupled node pair instead of one per pair and
    node pair (a 3D particle-facet pair alone would give (27 x 3)^2 = 6561 triplets). Only the
    upper triangle (column node >= row node) is summed; the lower one is its transpose (the
    result is exactly symmetric). The pairs are first ordered by the smallest free node of their
    stencils (a counting sort) and the blocks of their free points copied in that order, so that
    the pairs of one row, neighbours in space, are also neighbours in memory.

    Returns ``rows, cols (nnz,) int64`` and ``vals (nnz,)``: the upper blocks row by row, then
    the transposes of the strictly upper ones; nnz = d^2 x coupled node pairs.
    """
    n, m = pair_points.shape
    k = nodes.shape[1]
    d = hess.shape[1] // m if m else 1
    dd = d * d
    n_free = 0
    for i in range(dof_node.size):
        n_free = max(n_free, dof_node[i] + 1)
    # per pair: free entries, free points, and the sort key (smallest free node)
    key = np.full(n, -1, dtype=np.int64)
    n_ent = np.zeros(n, dtype=np.int64)
    n_pts = np.zeros(n, dtype=np.int64)
    bucket = np.zeros(n_free + 1, dtype=np.int64)
    for p in range(n):
        for a in range(m):
            c = pair_points[p, a]
            cnt = 0
            for j in range(k):
                if weights[c, j] != 0.0:
                    dn = dof_node[nodes[c, j]]
                    if dn >= 0:
                        cnt += 1
                        if key[p] < 0 or dn < key[p]:
                            key[p] = dn
            if cnt:
                n_ent[p] += cnt
                n_pts[p] += 1
        if key[p] >= 0:
            bucket[key[p] + 1] += 1
    for r in range(n_free):
        bucket[r + 1] += bucket[r]
    n_act = bucket[n_free]
    order = np.empty(n_act, dtype=np.int64)
    for p in range(n):
        if key[p] >= 0:
            order[bucket[key[p]]] = p
            bucket[key[p]] += 1
    # entries (node, free-point slot, weight) and free-point blocks, in that order
    estart = np.zeros(n_act + 1, dtype=np.int64)
    hstart = np.zeros(n_act + 1, dtype=np.int64)
    for q in range(n_act):
        p = order[q]
        estart[q + 1] = estart[q] + n_ent[p]
        hstart[q + 1] = hstart[q] + (n_pts[p] * d) ** 2
    total = estart[n_act]
    e_node = np.empty(total, dtype=np.int64)
    e_slot = np.empty(total, dtype=np.int64)
    e_pair = np.empty(total, dtype=np.int64)
    e_w = np.empty(total)
    hc = np.empty(hstart[n_act])
    rstart = np.zeros(n_free + 1, dtype=np.int64)
    free_pt = np.empty(m, dtype=np.int64)
    pair_nf = np.empty(n_act, dtype=np.int64)
    t = 0
    for q in range(n_act):
        p = order[q]
        mf = 0
        for a in range(m):
            c = pair_points[p, a]
            has = False
            for j in range(k):
                w = weights[c, j]
                if w == 0.0:
                    continue
                dn = dof_node[nodes[c, j]]
                if dn < 0:
                    continue
                e_node[t] = dn
                e_slot[t] = mf
                e_pair[t] = q
                e_w[t] = w
                rstart[dn + 1] += 1
                t += 1
                has = True
            if has:
                free_pt[mf] = a
                mf += 1
        nf = mf * d
        pair_nf[q] = nf
        h0 = hstart[q]
        for a in range(mf):
            for b in range(mf):
                for i in range(d):
                    for j in range(d):
                        hc[h0 + (a * d + i) * nf + b * d + j] = hess[
                            p, free_pt[a] * d + i, free_pt[b] * d + j
                        ]
    # the entries of every row node (counting sort by node, pair order kept)
    for r in range(n_free):
        rstart[r + 1] += rstart[r]
    fill = rstart[:-1].copy()
    r_ent = np.empty(total, dtype=np.int64)
    for t in range(total):
        r = e_node[t]
        r_ent[fill[r]] = t
        fill[r] += 1
    # symbolic pass: blocks per row, upper triangle (column node >= row node) only
    marker = np.full(n_free, -1, dtype=np.int64)
    bptr = np.zeros(n_free + 1, dtype=np.int64)
    for r in range(n_free):
        cnt = 0
        for u in range(rstart[r], rstart[r + 1]):
            q = e_pair[r_ent[u]]
            for f in range(estart[q], estart[q + 1]):
                c = e_node[f]
                if c >= r and marker[c] != r:
                    marker[c] = r
                    cnt += 1
        bptr[r + 1] = bptr[r] + cnt
    n_up = bptr[n_free]
    block_row = np.empty(n_up, dtype=np.int64)
    block_col = np.empty(n_up, dtype=np.int64)
    upper = np.zeros(n_up * dd)
    # numeric pass: w_e w_f hess[slot_e block, slot_f block] into block (row node, col node);
    # a pair's entries come point by point, so its d x d block is loaded once per point
    marker[:] = -1
    block = np.empty(n_free, dtype=np.int64)
    hab = np.empty(dd)
    for r in range(n_free):
        pos = bptr[r]
        for u in range(rstart[r], rstart[r + 1]):
            e = r_ent[u]
            q = e_pair[e]
            we = e_w[e]
            nf = pair_nf[q]
            row0 = hstart[q] + e_slot[e] * d * nf
            current = -1
            for f in range(estart[q], estart[q + 1]):
                c = e_node[f]
                if c < r:
                    continue
                if e_slot[f] != current:
                    current = e_slot[f]
                    h0 = row0 + current * d
                    for i in range(d):
                        for j in range(d):
                            hab[i * d + j] = we * hc[h0 + i * nf + j]
                if marker[c] != r:
                    marker[c] = r
                    block[c] = pos
                    block_row[pos] = r
                    block_col[pos] = c
                    pos += 1
                base = block[c] * dd
                wf = e_w[f]
                for t in range(dd):
                    upper[base + t] += wf * hab[t]
    # triplets: the upper blocks, then the strictly upper ones transposed (the lower triangle)
    n_strict = 0
    for b in range(n_up):
        if block_col[b] != block_row[b]:
            n_strict += 1
    nnz = (n_up + n_strict) * dd
    rows = np.empty(nnz, dtype=np.int64)
    cols = np.empty(nnz, dtype=np.int64)
    vals = np.empty(nnz)
    low = n_up * dd
    for b in range(n_up):
        r = block_row[b]
        c = block_col[b]
        for i in range(d):
            for j in range(d):
                t = b * dd + i * d + j
                rows[t] = r * d + i
                cols[t] = c * d + j
                if c == r:  # sums in another order above and below the diagonal: symmetrise
                    vals[t] = 0.5 * (upper[t] + upper[b * dd + j * d + i])
                else:
                    vals[t] = upper[t]
        if c != r:
            for i in range(d):
                for j in range(d):
                    rows[low] = c * d + j
                    cols[low] = r * d + i
                    vals[low] = upper[b * dd + i * d + j]
                    low += 1
    return rows, cols, vals
