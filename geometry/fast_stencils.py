"""``particle_stencils`` with the compaction in numba: the same stencils, a fraction of the time.

:func:`geometry.grid.particle_stencils` compacts the stencil nodes with numpy (linear indices,
a dense mark array or ``np.unique``, a remap). Per explicit step that numpy work costs several
times the B-spline kernel itself (measured at 131k particles in 2D: 40-60 ms against 7 ms for
the kernel). :func:`fast_particle_stencils` does the compaction in one serial numba pass over
the P x K stencil entries (mark, prefix count, remap) and returns exactly what
``particle_stencils`` returns (same active nodes in the same lexicographic order, same
zero-weight redirection), falling back to it when the stencils' bounding box is too large for a
dense mark array (``geometry.grid._DENSE_LIMIT``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from geometry._grid_kernels import _stencils
from geometry.grid import (
    _DENSE_LIMIT,
    Grid,
    ParticleStencils,
    _points,
    particle_stencils,
    stencil_offsets,
)

__all__ = ["fast_particle_stencils"]


@njit(cache=True)
def _compact_dense(base, offsets, weights, grads, lo, stride, box_size, drop_zero):  # noqa: ANN001, ANN202
    """Compact stencil nodes ``(P, K)`` into the sorted active nodes of a dense box.

    Returns ``nodes (P, K)`` (indices into the active nodes) and the active linear indices
    ``(G,)`` in increasing (lexicographic) order.
    """
    n_p, k = weights.shape
    d = base.shape[1]
    lin = np.empty((n_p, k), dtype=np.int64)
    mark = np.zeros(box_size, dtype=np.int64)
    centre = (k - 1) // 2
    off_lin = np.zeros(k, dtype=np.int64)
    for a in range(k):
        for c in range(d):
            off_lin[a] += offsets[a, c] * stride[c]
    for p in range(n_p):
        b = 0
        for c in range(d):
            b += (base[p, c] - lo[c]) * stride[c]
        for a in range(k):
            value = b + off_lin[a]
            if drop_zero and weights[p, a] == 0.0:
                void = True
                for c in range(d):
                    if grads[p, a, c] != 0.0:
                        void = False
                if void:
                    value = b + off_lin[centre]
            lin[p, a] = value
            mark[value] = 1
    count = 0
    for j in range(box_size):
        if mark[j]:
            mark[j] = count
            count += 1
        else:
            mark[j] = -1
    active = np.empty(count, dtype=np.int64)
    for j in range(box_size):
        if mark[j] >= 0:
            active[mark[j]] = j
    for p in range(n_p):
        for a in range(k):
            lin[p, a] = mark[lin[p, a]]
    return lin, active


def fast_particle_stencils(
    grid: Grid, x: np.ndarray, *, drop_zero_weights: bool = True
) -> ParticleStencils:
    """What :func:`geometry.grid.particle_stencils` returns, compacted in numba (module doc)."""
    dim = grid.dim
    pts = _points(x, dim)
    n_particles = pts.shape[0]
    if n_particles == 0:
        return particle_stencils(grid, pts, drop_zero_weights=drop_zero_weights)
    xi = (pts - np.asarray(grid.origin)) / grid.dx
    if np.abs(xi).max() > 2.0**52:
        return particle_stencils(grid, pts, drop_zero_weights=drop_zero_weights)  # it raises
    offsets = stencil_offsets(dim)
    n_stencil = offsets.shape[0]
    base = np.empty((n_particles, dim), dtype=np.int64)
    weights = np.empty((n_particles, n_stencil))
    grads = np.empty((n_particles, n_stencil, dim))
    _stencils(xi, offsets, 1.0 / grid.dx, base, weights, grads)
    lo = base.min(axis=0)
    extent = base.max(axis=0) - lo + 3
    box_size = int(np.prod(extent.astype(np.float64)))
    if box_size > _DENSE_LIMIT or box_size > 8 * n_particles * n_stencil:
        return particle_stencils(grid, pts, drop_zero_weights=drop_zero_weights)
    stride = np.ones(dim, dtype=np.int64)
    for a in range(dim - 2, -1, -1):
        stride[a] = stride[a + 1] * extent[a + 1]
    nodes, active = _compact_dense(
        base, offsets, weights, grads, lo, stride, box_size, bool(drop_zero_weights)
    )
    active_ijk = np.empty((active.size, dim), dtype=np.int64)
    rest = active
    for a in range(dim):  # d vectorised passes, not a loop over nodes
        active_ijk[:, a] = rest // stride[a] + lo[a]
        rest = rest % stride[a]
    return ParticleStencils(
        nodes=nodes,
        weights=weights,
        grads=grads,
        active_ijk=active_ijk,
        active_x=grid.node_positions(active_ijk),
    )
