"""numba kernels of the per-material grid moments of LR contact (Nairn et al., "LR"): mass
gradients (LR eq. 11) and the point clouds of the contact nodes (the first mass moments of the
CP separation, LR eq. 16, are ``bfemp.mpm._multimaterial_kernels.mass_moments``). One serial
scatter over the particles each (bit-for-bit reproducible whatever the thread count).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["mass_gradients", "point_clouds"]


@njit(cache=True)
def mass_gradients(
    nodes: np.ndarray,
    grads: np.ndarray,
    mass: np.ndarray,
    material: np.ndarray,
    n_nodes: int,
    n_materials: int,
) -> np.ndarray:
    """grad m_i^alpha = sum_{p in alpha} m_p grad w_ip ``(n_materials, n_nodes, d)`` (LR eq. 11
    with the weight m_p; V_p or A_p gives the paper's volume or area gradient)."""
    n_p, n_s = nodes.shape
    d = grads.shape[2]
    out = np.zeros((n_materials, n_nodes, d))
    for p in range(n_p):
        mat = material[p]
        for s in range(n_s):
            i = nodes[p, s]
            if i < 0:
                continue
            for a in range(d):
                out[mat, i, a] += mass[p] * grads[p, s, a]
    return out


@njit(cache=True)
def point_clouds(
    nodes: np.ndarray,
    weights: np.ndarray,
    material: np.ndarray,
    row_node: np.ndarray,
    alpha: np.ndarray,
    beta: np.ndarray,
    n_nodes: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """CSR point clouds of C contact rows: ``(cloud_ptr (C+1,), cloud_idx (K,), cloud_side
    (K,) int8)``. Row r at grid node ``row_node[r]`` holds every particle p with w_ip > 0 of
    material ``alpha[r]`` (side -1) or ``beta[r]`` (+1; beta < 0: every other material, the
    lumping of LR eq. 50). Serial, two passes (count, fill); particles in index order."""
    n_p, n_s = nodes.shape
    n_c = row_node.shape[0]
    # rows of each grid node (CSR over the nodes)
    node_ptr = np.zeros(n_nodes + 1, dtype=np.int64)
    for r in range(n_c):
        node_ptr[row_node[r] + 1] += 1
    for i in range(n_nodes):
        node_ptr[i + 1] += node_ptr[i]
    node_rows = np.empty(n_c, dtype=np.int64)
    fill = node_ptr[:-1].copy()
    for r in range(n_c):
        node_rows[fill[row_node[r]]] = r
        fill[row_node[r]] += 1
    cloud_ptr = np.zeros(n_c + 1, dtype=np.int64)
    for sweep in range(2):
        if sweep == 1:
            for r in range(n_c):
                cloud_ptr[r + 1] += cloud_ptr[r]
            cursor = cloud_ptr[:-1].copy()
            cloud_idx = np.empty(cloud_ptr[n_c], dtype=np.int64)
            cloud_side = np.empty(cloud_ptr[n_c], dtype=np.int8)
        for p in range(n_p):
            mat = material[p]
            for s in range(n_s):
                i = nodes[p, s]
                if i < 0 or not weights[p, s] > 0.0:
                    continue
                for k in range(node_ptr[i], node_ptr[i + 1]):
                    r = node_rows[k]
                    if mat == alpha[r]:
                        side = -1
                    elif beta[r] < 0 or mat == beta[r]:
                        side = 1
                    else:
                        continue
                    if sweep == 0:
                        cloud_ptr[r + 1] += 1
                    else:
                        cloud_idx[cursor[r]] = p
                        cloud_side[cursor[r]] = side
                        cursor[r] += 1
    return cloud_ptr, cloud_idx, cloud_side
