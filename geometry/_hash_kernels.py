"""numba kernels of :mod:`geometry.broadphase`: primitive boxes and a uniform spatial hash.

Private: array-in / array-out, no validation (the drivers in :mod:`geometry.broadphase` validate).
Boxes are always 3D here (2D boxes are padded with a zero z interval, one cell thick).

Layout (CSR, no dictionaries): the inserted boxes ``b`` are scattered into the cells they cover,
cell ``c`` going to bucket ``hash(c) & mask`` of a power-of-two table; ``bucket_start`` (T + 1,)
is the prefix sum of the bucket counts and ``bucket_items`` lists box indices bucket by bucket.
A query box visits the buckets of the cells it covers and tests every listed box with the exact
closed-interval overlap predicate

    overlap(i, j)  <=>  a_lo[i, k] <= b_hi[j, k]  and  b_lo[j, k] <= a_hi[i, k]  for every axis k,

the same predicate as the brute-force reference, so the hash returns exactly the overlapping
pairs. Cell coordinates ``floor((x - origin) / h)`` are monotone in ``x`` (rounding of the
subtraction and the product is monotone, so is floor and the clamp), hence two overlapping boxes
always share a cell. A pair is reported only from the first cell their cell ranges share
(componentwise max of the two lower cells), so a pair seen from several common cells is counted
once; hash collisions can still list a box twice in one bucket, which the caller removes.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

# Large primes of the classic spatial-hash function (Teschner et al. 2003).
_P1 = 73856093
_P2 = 19349663
_P3 = 83492791


@njit(cache=True)
def _cell(x: float, origin: float, inv_h: float, n_max: float) -> int:
    """Cell coordinate of ``x`` on one axis, clamped to [0, n_max]; monotone in ``x``."""
    t = (x - origin) * inv_h
    if t <= 0.0:
        return 0
    if t >= n_max:
        return np.int64(n_max)
    return np.int64(np.floor(t))


@njit(cache=True)
def _bucket(cx: int, cy: int, cz: int, mask: int) -> int:
    """Bucket of cell (cx, cy, cz) in a table of ``mask + 1`` buckets (a power of two)."""
    return ((cx * _P1) ^ (cy * _P2) ^ (cz * _P3)) & mask


@njit(cache=True, parallel=True)
def _boxes(
    x0: np.ndarray, x1: np.ndarray, cells: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> None:
    """Boxes of the start and end positions of each primitive's vertices, padded to 3D.

    Args:
        x0, x1: (V, d) start / end vertex positions in m, d = 2 or 3 (the same array if static).
        cells: (N, k) int64 vertex indices of the primitives (k = 1 for points).
        lo, hi: (N, 3) outputs, box corners in m (zero z interval when d = 2).
    """
    dim = x0.shape[1]
    for i in prange(cells.shape[0]):
        for a in range(3):
            if a >= dim:
                lo[i, a] = 0.0
                hi[i, a] = 0.0
                continue
            v = cells[i, 0]
            low = min(x0[v, a], x1[v, a])
            high = max(x0[v, a], x1[v, a])
            for m in range(1, cells.shape[1]):
                v = cells[i, m]
                low = min(low, min(x0[v, a], x1[v, a]))
                high = max(high, max(x0[v, a], x1[v, a]))
            lo[i, a] = low
            hi[i, a] = high


@njit(cache=True, parallel=True)
def _cell_ranges(
    lo: np.ndarray,
    hi: np.ndarray,
    origin: np.ndarray,
    top: np.ndarray,
    inv_h: float,
    n_max: np.ndarray,
    cell_lo: np.ndarray,
    cell_hi: np.ndarray,
    active: np.ndarray,
) -> float:
    """Clamped cell ranges of N boxes and the number of cells the active ones cover.

    Args:
        lo, hi: (N, 3) box corners in m.
        origin, top: (3,) corners of the hashed domain in m (the box of all inserted boxes).
        inv_h: 1 / cell size in 1/m.
        n_max: (3,) float, largest cell coordinate per axis.
        cell_lo, cell_hi: (N, 3) int64 outputs, inclusive cell ranges.
        active: (N,) bool output, whether the box overlaps the domain (closed intervals); a box
            that misses it cannot overlap any inserted box.

    Returns:
        The total number of cells covered by the active boxes (float, no overflow).
    """
    total = 0.0
    for i in prange(lo.shape[0]):
        inside = True
        cells = 1.0
        for k in range(3):
            if lo[i, k] > top[k] or origin[k] > hi[i, k]:
                inside = False
            c0 = _cell(lo[i, k], origin[k], inv_h, n_max[k])
            c1 = _cell(hi[i, k], origin[k], inv_h, n_max[k])
            cell_lo[i, k] = c0
            cell_hi[i, k] = c1
            cells *= c1 - c0 + 1
        active[i] = inside
        if inside:
            total += cells
    return total


@njit(cache=True)
def _build_table(cell_lo: np.ndarray, cell_hi: np.ndarray, mask: int) -> tuple:
    """Counting-sort the boxes into the hash table.

    Args:
        cell_lo, cell_hi: (S, 3) int64 inclusive cell ranges of the inserted boxes.
        mask: table size minus one (table size is a power of two).

    Returns:
        ``bucket_start`` (T + 1,) int64 prefix sums and ``bucket_items`` (M,) int64 box indices.
    """
    n_buckets = mask + 1
    bucket_start = np.zeros(n_buckets + 1, dtype=np.int64)
    for j in range(cell_lo.shape[0]):
        for cx in range(cell_lo[j, 0], cell_hi[j, 0] + 1):
            for cy in range(cell_lo[j, 1], cell_hi[j, 1] + 1):
                for cz in range(cell_lo[j, 2], cell_hi[j, 2] + 1):
                    bucket_start[_bucket(cx, cy, cz, mask) + 1] += 1
    for t in range(n_buckets):
        bucket_start[t + 1] += bucket_start[t]
    bucket_items = np.empty(bucket_start[n_buckets], dtype=np.int64)
    cursor = bucket_start[:n_buckets].copy()
    for j in range(cell_lo.shape[0]):
        for cx in range(cell_lo[j, 0], cell_hi[j, 0] + 1):
            for cy in range(cell_lo[j, 1], cell_hi[j, 1] + 1):
                for cz in range(cell_lo[j, 2], cell_hi[j, 2] + 1):
                    b = _bucket(cx, cy, cz, mask)
                    bucket_items[cursor[b]] = j
                    cursor[b] += 1
    return bucket_start, bucket_items


@njit(cache=True)
def _overlap(a_lo: np.ndarray, a_hi: np.ndarray, b_lo: np.ndarray, b_hi: np.ndarray) -> bool:
    """Closed-interval overlap of two (3,) boxes on every axis."""
    for k in range(3):
        if a_lo[k] > b_hi[k] or b_lo[k] > a_hi[k]:
            return False
    return True


@njit(cache=True)
def _scan(a_lo: np.ndarray, a_hi: np.ndarray, b_lo: np.ndarray, b_hi: np.ndarray) -> np.ndarray:
    """Every overlapping (a, b) box pair, testing all P S pairs (count, then store): (n, 2) int64
    rows, unique and sorted as found. No table to build: on small sets cheaper than the hash."""
    n = 0
    for i in range(a_lo.shape[0]):
        for j in range(b_lo.shape[0]):
            n += _overlap(a_lo[i], a_hi[i], b_lo[j], b_hi[j])
    out = np.empty((n, 2), dtype=np.int64)
    n = 0
    for i in range(a_lo.shape[0]):
        for j in range(b_lo.shape[0]):
            if _overlap(a_lo[i], a_hi[i], b_lo[j], b_hi[j]):
                out[n, 0] = i
                out[n, 1] = j
                n += 1
    return out


@njit(cache=True)
def _query_one(
    i: int,
    a_lo: np.ndarray,
    a_hi: np.ndarray,
    a_cell_lo: np.ndarray,
    a_cell_hi: np.ndarray,
    b_lo: np.ndarray,
    b_hi: np.ndarray,
    b_cell_lo: np.ndarray,
    bucket_start: np.ndarray,
    bucket_items: np.ndarray,
    mask: int,
    out_b: np.ndarray,
    offset: int,
    write: bool,
) -> int:
    """Count (and with ``write``, store from ``out_b[offset]``) the boxes overlapping box i."""
    n = 0
    for cx in range(a_cell_lo[i, 0], a_cell_hi[i, 0] + 1):
        for cy in range(a_cell_lo[i, 1], a_cell_hi[i, 1] + 1):
            for cz in range(a_cell_lo[i, 2], a_cell_hi[i, 2] + 1):
                b = _bucket(cx, cy, cz, mask)
                for t in range(bucket_start[b], bucket_start[b + 1]):
                    j = bucket_items[t]
                    # first common cell of the two ranges, the only one that reports the pair
                    if max(a_cell_lo[i, 0], b_cell_lo[j, 0]) != cx:
                        continue
                    if max(a_cell_lo[i, 1], b_cell_lo[j, 1]) != cy:
                        continue
                    if max(a_cell_lo[i, 2], b_cell_lo[j, 2]) != cz:
                        continue
                    if not _overlap(a_lo[i], a_hi[i], b_lo[j], b_hi[j]):
                        continue
                    if write:
                        out_b[offset + n] = j
                    n += 1
    return n


@njit(cache=True, parallel=True)
def _query(
    a_lo: np.ndarray,
    a_hi: np.ndarray,
    a_cell_lo: np.ndarray,
    a_cell_hi: np.ndarray,
    a_active: np.ndarray,
    b_lo: np.ndarray,
    b_hi: np.ndarray,
    b_cell_lo: np.ndarray,
    bucket_start: np.ndarray,
    bucket_items: np.ndarray,
    mask: int,
) -> tuple:
    """All overlapping (query, inserted) box pairs, in two race-free passes over the queries.

    Args:
        a_lo, a_hi: (P, 3) query boxes in m; a_cell_lo, a_cell_hi: (P, 3) int64 cell ranges.
        a_active: (P,) bool, False for query boxes that miss the hashed domain entirely.
        b_lo, b_hi: (S, 3) inserted boxes in m; b_cell_lo: (S, 3) int64 lower cells.
        bucket_start, bucket_items: the table of :func:`_build_table`; mask: table size - 1.

    Returns:
        ``counts`` (P,) int64 pairs per query and ``out_b`` (n,) int64 inserted box indices,
        grouped by query in increasing order (``counts`` gives the group sizes).
    """
    n_query = a_lo.shape[0]
    counts = np.zeros(n_query, dtype=np.int64)
    offsets = np.zeros(n_query + 1, dtype=np.int64)
    out_b = np.empty(0, dtype=np.int64)
    for write in (False, True):  # count each query's pairs, then store them at its offset
        for i in prange(n_query):
            if a_active[i] and (counts[i] > 0 or not write):
                n = _query_one(
                    i,
                    a_lo,
                    a_hi,
                    a_cell_lo,
                    a_cell_hi,
                    b_lo,
                    b_hi,
                    b_cell_lo,
                    bucket_start,
                    bucket_items,
                    mask,
                    out_b,
                    offsets[i],
                    write,
                )
                if not write:
                    counts[i] = n
        if not write:
            for i in range(n_query):
                offsets[i + 1] = offsets[i] + counts[i]
            out_b = np.empty(offsets[n_query], dtype=np.int64)
    return counts, out_b
