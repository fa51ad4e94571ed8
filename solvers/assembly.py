"""Sparse assembly of COO triplets into CSC matrices, with sparsity-pattern reuse.

Every energy term returns its Hessian as :class:`Triplets` (row, column, value; duplicates
allowed, they are summed).  :class:`TripletAssembler` turns them into a ``scipy.sparse``
CSC matrix.  The expensive part of assembly is finding, for every triplet, the slot of the
CSC ``data`` array it adds into (counting sorts of the triplets by column and by slot,
``solvers._pattern_kernels``).  That map depends only on
the ``rows``/``cols`` arrays, so it is cached and reused while the next call brings equal
arrays (triplets that carry the ``pattern_key`` of the last call are taken as equal without a
comparison: :class:`TripletStacker` keys the patterns it keeps); assembly then is one parallel
pass that sums each slot's values in triplet order, which gives the same bits as
``np.bincount(slots, weights=vals)``.

Elimination of fixed degrees of freedom happens here too: with a ``free`` mask the assembler
returns the principal submatrix ``A[free][:, free]`` directly (triplets touching a fixed DOF
go to a discarded slot), so the reduced system needs no extra sparse slicing.

Pattern versions are drawn from one process-wide counter, so two assemblers never hand the
same version to a linear solver for different patterns (a solver keyed on the version would
otherwise reuse a wrong symbolic factorisation).
"""

from __future__ import annotations

import itertools
import logging
import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numba import njit, prange

from solvers._pattern_kernels import _csc_pattern

__all__ = ["TripletAssembler", "TripletStacker", "Triplets", "new_pattern_key"]

logger = logging.getLogger(__name__)

# Unique sparsity-pattern versions across all assemblers of the process (0 means "none yet").
_PATTERN_VERSIONS = itertools.count(1)
# Unique keys of kept triplet patterns (Triplets.pattern_key)
_PATTERN_KEYS = itertools.count(1)


def new_pattern_key() -> int:
    """A process-unique :attr:`Triplets.pattern_key` for a newly kept pair of index arrays."""
    return next(_PATTERN_KEYS)


@dataclass(frozen=True)
class Triplets:
    """A sparse matrix in COO form; duplicate (row, col) entries are summed on assembly.

    Attributes:
        rows: row indices (nnz,) int64.
        cols: column indices (nnz,) int64.
        vals: values (nnz,) float64, in the units of the matrix (e.g. N/m for a Hessian of J
            with respect to positions in m).
        pattern_key: None, or a process-unique id (:func:`new_pattern_key`) its maker gives
            one pair of ``rows``/``cols`` arrays, which it keeps and never modifies: triplets
            with equal keys have the same pattern, so :class:`TripletAssembler` skips the
            comparison of the index arrays.
    """

    rows: np.ndarray
    cols: np.ndarray
    vals: np.ndarray
    pattern_key: int | None = None

    def __post_init__(self) -> None:
        rows = np.ascontiguousarray(self.rows, dtype=np.int64)
        cols = np.ascontiguousarray(self.cols, dtype=np.int64)
        vals = np.ascontiguousarray(self.vals, dtype=np.float64)
        if rows.ndim != 1 or cols.ndim != 1 or vals.ndim != 1:
            raise ValueError(
                "Triplets rows, cols and vals must be 1-D, got shapes "
                f"{rows.shape}, {cols.shape}, {vals.shape}"
            )
        if not rows.shape == cols.shape == vals.shape:
            raise ValueError(
                "Triplets rows, cols and vals must have equal lengths, got "
                f"{rows.size}, {cols.size}, {vals.size}"
            )
        object.__setattr__(self, "rows", rows)
        object.__setattr__(self, "cols", cols)
        object.__setattr__(self, "vals", vals)

    @property
    def nnz(self) -> int:
        """Number of stored triplets (duplicates counted)."""
        return int(self.vals.size)

    @staticmethod
    def empty() -> Triplets:
        """Triplets of the zero matrix (no entries)."""
        return Triplets(np.empty(0, np.int64), np.empty(0, np.int64), np.empty(0, np.float64))

    @staticmethod
    def concatenate(parts: list[Triplets]) -> Triplets:
        """Stack several triplet sets into one (the sum of the matrices they describe)."""
        if len(parts) == 0:
            return Triplets.empty()
        if len(parts) == 1:
            return parts[0]
        return Triplets(
            np.concatenate([t.rows for t in parts]),
            np.concatenate([t.cols for t in parts]),
            np.concatenate([t.vals for t in parts]),
        )

    @staticmethod
    def from_blocks(block_dofs: np.ndarray, blocks: np.ndarray) -> Triplets:
        """Scatter dense local blocks into global triplets.

        Args:
            block_dofs: global DOF index of every local row/column, (S, k) integer.
            blocks: local matrices (S, k, k); ``blocks[s, a, b]`` goes to
                ``(block_dofs[s, a], block_dofs[s, b])``.

        Returns:
            Triplets with ``S * k * k`` entries, block-major.
        """
        block_dofs = np.asarray(block_dofs)
        blocks = np.asarray(blocks, dtype=np.float64)
        if block_dofs.ndim != 2:
            raise ValueError(f"block_dofs must be (S, k), got shape {block_dofs.shape}")
        s, k = block_dofs.shape
        if blocks.shape != (s, k, k):
            raise ValueError(f"blocks must have shape {(s, k, k)}, got {blocks.shape}")
        rows = np.broadcast_to(block_dofs[:, :, None], (s, k, k)).ravel()
        cols = np.broadcast_to(block_dofs[:, None, :], (s, k, k)).ravel()
        return Triplets(rows, cols, blocks.ravel())

    def scaled(self, factor: float) -> Triplets:
        """The same pattern with values multiplied by ``factor`` (arrays of indices shared)."""
        return Triplets(self.rows, self.cols, self.vals * float(factor))


class TripletStacker:
    """Stacks triplet sets like :meth:`Triplets.concatenate`, reusing the stacked index arrays.

    While every part brings the very same ``rows``/``cols`` array objects as at the last call
    (terms whose pattern is fixed for a step return their cached index arrays), the stacked
    index arrays of the last call are returned again and only the values are concatenated (and
    ``NodeFrames.rotate`` keeps its pattern work). Index arrays handed in must not be modified
    in place (the terms' cached patterns never are).
    """

    def __init__(self) -> None:
        self._parts: list[tuple[np.ndarray, np.ndarray]] = []
        self._rows: np.ndarray | None = None
        self._cols: np.ndarray | None = None
        self._key: int | None = None

    def stack(self, parts: list[Triplets]) -> Triplets:
        """The sum of ``parts`` as one triplet set (entries in the order of the parts)."""
        parts = [t for t in parts if t.nnz]  # empty parts bring fresh arrays and no entries
        if len(parts) <= 1:
            return Triplets.concatenate(parts)
        same = len(parts) == len(self._parts) and all(
            t.rows is r and t.cols is c for t, (r, c) in zip(parts, self._parts, strict=True)
        )
        if not same:
            stacked = Triplets.concatenate(parts)
            # references keep the arrays alive, so their identity cannot be reused
            self._parts = [(t.rows, t.cols) for t in parts]
            self._rows, self._cols = stacked.rows, stacked.cols
            self._key = new_pattern_key()
            return Triplets(self._rows, self._cols, stacked.vals, pattern_key=self._key)
        vals = np.concatenate([t.vals for t in parts])
        return Triplets(self._rows, self._cols, vals, pattern_key=self._key)


class TripletAssembler:
    """Assembles :class:`Triplets` into an ``n x n`` (or reduced) CSC matrix, reusing patterns.

    Args:
        n: size of the full matrix (number of DOFs).
        free: optional bool mask (n,); when given, :meth:`assemble` returns the principal
            submatrix on the free DOFs, of size ``n_free x n_free`` (free DOFs renumbered in
            increasing order). Triplets touching a non-free DOF are dropped.

    Attributes:
        pattern_changed: whether the last :meth:`assemble` call rebuilt the pattern.
        last_pattern_s: seconds the last :meth:`assemble` call spent on the pattern (comparing
            and rebuilding it; 0 when keyed as the last one).
        pattern_version: process-unique id of the current pattern (0 before the first call).
        n_rebuilds: number of pattern rebuilds so far.
    """

    def __init__(self, n: int, *, free: np.ndarray | None = None) -> None:
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
            raise ValueError(f"TripletAssembler n must be a non-negative int, got {n!r}")
        self.n = int(n)
        if free is None:
            self._full_to_reduced = None
            self.n_out = self.n
        else:
            free = np.asarray(free)
            if free.dtype != np.bool_ or free.shape != (self.n,):
                raise ValueError(
                    f"TripletAssembler free must be a bool mask of shape ({self.n},), "
                    f"got dtype {free.dtype} and shape {free.shape}"
                )
            self.n_out = int(np.count_nonzero(free))
            full_to_reduced = np.full(self.n, -1, dtype=np.int64)
            full_to_reduced[free] = np.arange(self.n_out, dtype=np.int64)
            self._full_to_reduced = full_to_reduced
        self.pattern_changed = False
        self.last_pattern_s = 0.0
        self.pattern_version = 0
        self.n_rebuilds = 0
        self._rows: np.ndarray | None = None
        self._cols: np.ndarray | None = None
        self._slots: np.ndarray | None = None
        self._order: np.ndarray | None = None  # triplets sorted by slot (stable)
        self._starts: np.ndarray | None = None  # (nnz + 1,) first entry of each slot in _order
        self._input_key: int | None = None  # pattern_key of the last triplets assembled
        self._indices: np.ndarray | None = None
        self._indptr: np.ndarray | None = None

    def fits(self, n: int, free: np.ndarray | None) -> bool:
        """Whether this assembler assembles ``n x n`` systems reduced to the same ``free`` mask
        (so a caller may keep it, and its pattern, across solves)."""
        if n != self.n:
            return False
        if free is None or self._full_to_reduced is None:
            return free is None and self._full_to_reduced is None
        return bool(np.array_equal(free, self._full_to_reduced >= 0))

    def _same_pattern(self, t: Triplets) -> bool:
        if self._rows is None or self._rows.size != t.rows.size:
            return False
        if t.pattern_key is not None and t.pattern_key == self._input_key:
            return True  # the keyed pattern of the last call: no comparison needed
        return bool(np.array_equal(self._rows, t.rows) and np.array_equal(self._cols, t.cols))

    def _rebuild(self, rows: np.ndarray, cols: np.ndarray) -> None:
        n, m = self.n, self.n_out
        if rows.size and (rows.min() < 0 or cols.min() < 0 or rows.max() >= n or cols.max() >= n):
            bad = np.flatnonzero((rows < 0) | (rows >= n) | (cols < 0) | (cols >= n))
            raise ValueError(
                f"Triplets index out of range [0, {n}) at triplet(s) {bad[:10].tolist()}: "
                f"rows {rows[bad[:10]].tolist()}, cols {cols[bad[:10]].tolist()}"
            )
        if self._full_to_reduced is None:
            r, c = rows.astype(np.int64, copy=False), cols.astype(np.int64, copy=False)
        else:  # dropped triplets (a fixed DOF) get -1 and add into one extra slot, cut off
            r, c = self._full_to_reduced[rows], self._full_to_reduced[cols]
        # counting sorts (solvers._pattern_kernels): the arrays np.unique of the column-major
        # keys c * m + r and a stable argsort of the slots would give, in O(T + m)
        indptr, indices, slots, order, starts = _csc_pattern(r, c, m)
        nnz = indices.size
        index_dtype = np.int32 if max(nnz, m) < np.iinfo(np.int32).max else np.int64
        self._indices = indices.astype(index_dtype)
        self._indptr = indptr.astype(index_dtype)
        self._slots = slots
        index = np.int32 if rows.size < np.iinfo(np.int32).max else np.int64
        self._order = order.astype(index)
        self._starts = starts
        self._rows = rows.copy()
        self._cols = cols.copy()
        self.n_rebuilds += 1
        self.pattern_version = next(_PATTERN_VERSIONS)
        logger.debug(
            "pattern rebuilt: %d triplets -> %d nonzeros in %d x %d (version %d)",
            rows.size,
            nnz,
            m,
            m,
            self.pattern_version,
        )

    def assemble(self, t: Triplets) -> sp.csc_matrix:
        """Sum the triplets into a CSC matrix (canonical: sorted indices, no duplicates).

        Args:
            t: triplets with indices in ``[0, n)``.

        Returns:
            ``csc_matrix`` of shape ``(n_out, n_out)`` (``n_out = n`` without a ``free`` mask).
            Consecutive results with the same pattern share the memory of ``indices``/``indptr``
            arrays (do not modify them); ``data`` is always a new array.
        """
        if not isinstance(t, Triplets):
            raise ValueError(f"assemble expects Triplets, got {type(t).__name__}")
        start = time.perf_counter()
        self.pattern_changed = not self._same_pattern(t)
        if self.pattern_changed:
            self._rebuild(t.rows, t.cols)
        self.last_pattern_s = time.perf_counter() - start
        self._input_key = t.pattern_key
        data = _slot_sums(t.vals, self._order, self._starts)
        m = self.n_out
        return sp.csc_matrix((data, self._indices, self._indptr), shape=(m, m), copy=False)


@njit(cache=True, parallel=True)
def _slot_sums(vals, order, starts):  # noqa: ANN001, ANN202
    """data (nnz,): data[j] = sum of vals[order[q]] for q in [starts[j], starts[j + 1]).

    ``order`` lists the triplets slot by slot in increasing triplet index, so each sum runs in
    the order ``np.bincount`` adds in, from 0.0: the same bits, computed in parallel over slots.
    """
    nnz = starts.size - 1
    out = np.empty(nnz)
    for j in prange(nnz):
        acc = 0.0
        for q in range(starts[j], starts[j + 1]):
            acc += vals[order[q]]
        out[j] = acc
    return out
