"""numba kernel of :class:`solvers.assembly.TripletAssembler`'s pattern: CSC structure and slots.

From the (reduced) row and column of every triplet it builds, in O(T + m) with counting sorts
and a dense marker instead of the comparison sorts of ``np.unique`` and ``np.argsort``, the
same arrays as

    keys = col * m + row
    unique, slot = np.unique(keys, return_inverse=True)     # indices, indptr from unique
    order = np.argsort(slot, kind="stable")                 # triplets slot by slot

so that ``TripletAssembler`` gives the same matrices, bit for bit (``_slot_sums`` adds each
slot's entries in the order ``order`` lists them).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _csc_pattern(rows, cols, m):  # noqa: ANN001, ANN202
    """CSC pattern of the triplets ``(rows[t], cols[t])`` (T,) int64 in ``[0, m)``, or -1 for a
    dropped triplet (a row or column not kept).

    Returns:
        ``(indptr (m + 1,), indices (nnz,), slots (T,), order (T,), starts (nnz + 1,))``, all
        int64: the sorted-by-column-then-row unique entries, each triplet's entry (``nnz`` for
        a dropped one), the triplets listed entry by entry in increasing triplet index (dropped
        ones last) and the first position in ``order`` of each entry.
    """
    n_t = rows.size
    # 1. triplets bucketed by column, stable (counting sort)
    col_start = np.zeros(m + 1, dtype=np.int64)
    for t in range(n_t):
        if rows[t] >= 0 and cols[t] >= 0:
            col_start[cols[t] + 1] += 1
    for c in range(m):
        col_start[c + 1] += col_start[c]
    by_col = np.empty(col_start[m], dtype=np.int64)
    fill = col_start[:m].copy()
    for t in range(n_t):
        if rows[t] >= 0 and cols[t] >= 0:
            by_col[fill[cols[t]]] = t
            fill[cols[t]] += 1
    # 2. per column, its distinct rows (dense marker), sorted: indices and indptr
    mark = np.full(m, -1, dtype=np.int64)
    indptr = np.zeros(m + 1, dtype=np.int64)
    indices = np.empty(by_col.size, dtype=np.int64)  # at most one entry per triplet
    for c in range(m):
        start = indptr[c]
        n = 0
        for q in range(col_start[c], col_start[c + 1]):
            r = rows[by_col[q]]
            if mark[r] != c:
                mark[r] = c
                indices[start + n] = r
                n += 1
        indices[start : start + n] = np.sort(indices[start : start + n])
        indptr[c + 1] = start + n
    nnz = indptr[m]
    # 3. each triplet's entry: the rank of its row in its column (``mark`` now maps row -> slot)
    slots = np.full(n_t, nnz, dtype=np.int64)
    for c in range(m):
        for s in range(indptr[c], indptr[c + 1]):
            mark[indices[s]] = s
        for q in range(col_start[c], col_start[c + 1]):
            t = by_col[q]
            slots[t] = mark[rows[t]]
    # 4. triplets entry by entry, stable (counting sort; dropped ones in the extra slot nnz)
    starts = np.zeros(nnz + 2, dtype=np.int64)
    for t in range(n_t):
        starts[slots[t] + 1] += 1
    for s in range(nnz + 1):
        starts[s + 1] += starts[s]
    order = np.empty(n_t, dtype=np.int64)
    fill = starts[: nnz + 1].copy()
    for t in range(n_t):
        order[fill[slots[t]]] = t
        fill[slots[t]] += 1
    return indptr, indices[:nnz].copy(), slots, order, starts[: nnz + 1].copy()
