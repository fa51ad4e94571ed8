"""numba kernels of :mod:`geometry.sampling`: bucketed point location in simplex meshes.

Cells are put in the bins of a uniform bucketing grid overlapped by their bounding boxes
(compressed rows ``start``/``items``); a point then tests only the cells of its own bin, so
locating P points among m cells costs O(P + m) for meshes of roughly uniform cell size.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from geometry.inside import simplex_depth


@njit(cache=True)
def _linear_bin(b: np.ndarray, n_bins: np.ndarray) -> int:
    """Linear index of the integer bin coordinates b (d,), first axis slowest."""
    out = 0
    for a in range(b.shape[0]):
        out = out * n_bins[a] + b[a]
    return out


@njit(cache=True)
def _next_bin(b: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> bool:
    """Advance the odometer b (d,) through the bin box lo..hi (inclusive); False when done."""
    a = b.shape[0] - 1
    while a >= 0:
        b[a] += 1
        if b[a] <= hi[a]:
            return True
        b[a] = lo[a]
        a -= 1
    return False


@njit(cache=True)
def _bin_cells(cell_lo: np.ndarray, cell_hi: np.ndarray, n_bins: np.ndarray) -> tuple:
    """Compressed rows of the cells overlapping each bin.

    Args:
        cell_lo, cell_hi: (m, d) int64 inclusive bin ranges of each cell's bounding box.
        n_bins: (d,) int64 number of bins per axis.

    Returns:
        ``(start, items)``: start (B + 1,) int64 offsets and items (nnz,) int64 cell indices,
        ascending within each bin.
    """
    n_cells, dim = cell_lo.shape
    total = 1
    for a in range(dim):
        total *= n_bins[a]
    start = np.zeros(total + 1, dtype=np.int64)
    b = np.empty(dim, dtype=np.int64)
    for c in range(n_cells):
        b[:] = cell_lo[c]
        while True:
            start[_linear_bin(b, n_bins) + 1] += 1
            if not _next_bin(b, cell_lo[c], cell_hi[c]):
                break
    for i in range(total):
        start[i + 1] += start[i]
    fill = start[:-1].copy()
    items = np.empty(start[total], dtype=np.int64)
    for c in range(n_cells):
        b[:] = cell_lo[c]
        while True:
            lin = _linear_bin(b, n_bins)
            items[fill[lin]] = c
            fill[lin] += 1
            if not _next_bin(b, cell_lo[c], cell_hi[c]):
                break
    return start, items


@njit(cache=True, parallel=True)
def _locate(
    x: np.ndarray,
    bin_lo: np.ndarray,
    inv_bin: float,
    n_bins: np.ndarray,
    start: np.ndarray,
    items: np.ndarray,
    verts: np.ndarray,
    valid: np.ndarray,
    tol: float,
    out: np.ndarray,
) -> None:
    """Index of a cell containing each point, -1 if none.

    Args:
        x: (P, d) points in m.
        bin_lo: (d,) lower corner of the bucketing grid in m; inv_bin: 1 / bin size in 1/m.
        n_bins, start, items: the bucketing grid and its compressed rows (see _bin_cells).
        verts: (m, d + 1, d) vertices of each cell in m; valid: (m,) False for degenerate
            cells (skipped).
        tol: barycentric tolerance: inside when every barycentric coordinate is >= -tol
            (:func:`geometry.inside.simplex_depth`, inclusive convention).
        out: (P,) int64 output. Each point writes only its own entry (race-free).
    """
    n_points, dim = x.shape
    for p in prange(n_points):
        out[p] = -1
        b = np.empty(dim, dtype=np.int64)
        inside_box = True
        for a in range(dim):
            t = (x[p, a] - bin_lo[a]) * inv_bin
            if t < -1e-9 or t > n_bins[a] + 1e-9:
                inside_box = False
            b[a] = min(max(np.int64(np.floor(t)), 0), n_bins[a] - 1)
        if not inside_box:
            continue
        lin = _linear_bin(b, n_bins)
        for j in range(start[lin], start[lin + 1]):
            c = items[j]
            if not valid[c]:
                continue
            if simplex_depth(x[p], verts[c]) >= -tol:
                out[p] = c
                break
