"""numba kernels: chain rule from collision points (affine images of nodes) to node DOFs.

A pair has m collision points; point c sits at sum_k w[c, k] y[nodes[c, k]]. Local derivatives with
respect to the m points (m d entries) map to nodes by the weights (paper eq. 29): gradient rows
scale by w, Hessian blocks (a, b) by w_a w_b. Zero weights (padding, redirected B-spline entries)
are skipped, so a particle-edge pair in 2D yields (9 + 2)^2 node blocks, not (3 x 9)^2.
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
def _count_entries(pair_points, nodes, weights, dof_node):  # noqa: ANN001, ANN202
    """Number of free (node, node) block entries, per pair: (sum_a n_free(a))^2."""
    n, m = pair_points.shape
    k = nodes.shape[1]
    counts = np.zeros(n, dtype=np.int64)
    for p in range(n):
        free = 0
        for a in range(m):
            c = pair_points[p, a]
            for j in range(k):
                if weights[c, j] != 0.0 and dof_node[nodes[c, j]] >= 0:
                    free += 1
        counts[p] = free * free
    return counts


@njit(cache=True)
def _fill_triplets(hess, pair_points, nodes, weights, dof_node, starts, rows, cols, vals):  # noqa: ANN001, ANN202
    """Node-level triplets of the local Hessians ``hess (n, m d, m d)`` (d x d per node pair)."""
    n, m = pair_points.shape
    k = nodes.shape[1]
    d = hess.shape[1] // m
    for p in range(n):
        pos = starts[p] * d * d
        for a in range(m):
            ca = pair_points[p, a]
            for ja in range(k):
                wa = weights[ca, ja]
                if wa == 0.0:
                    continue
                da = dof_node[nodes[ca, ja]]
                if da < 0:
                    continue
                for b in range(m):
                    cb = pair_points[p, b]
                    for jb in range(k):
                        wb = weights[cb, jb]
                        if wb == 0.0:
                            continue
                        db = dof_node[nodes[cb, jb]]
                        if db < 0:
                            continue
                        w = wa * wb
                        for i in range(d):
                            for j in range(d):
                                rows[pos] = da * d + i
                                cols[pos] = db * d + j
                                vals[pos] = w * hess[p, a * d + i, b * d + j]
                                pos += 1
