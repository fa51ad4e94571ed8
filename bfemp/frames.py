"""Per-node rotated frames of the unknowns, to impose slip exactly (x_i = Q_i y_i).

For a node held on a boundary with unit normal n the unknowns are rotated into Q_i = [n, t1, (t2)]
and the normal coordinate y_i[0] is fixed: the node can only move tangentially. Everything the
solver sees is expressed in y: gradients Q^T g and Hessians Q^T H Q, expanded entry by entry from
the COO triplets (only entries touching a rotated node change; the pattern is fixed for a step).
"""

from __future__ import annotations

import numpy as np

from solvers.assembly import Triplets, new_pattern_key

__all__ = ["NodeFrames"]


class NodeFrames:
    """Rotations of some DOF nodes.

    Args:
        dim: spatial dimension d.
        n_dof: number of unknowns (d per DOF node).
        nodes: DOF-node indices ``(r,)`` that are rotated.
        frames: their orthonormal frames ``(r, d, d)`` (columns: local axes in world coordinates).
    """

    def __init__(self, dim: int, n_dof: int, nodes: np.ndarray, frames: np.ndarray) -> None:
        self.dim = dim
        self.n_dof = n_dof
        self.nodes = np.asarray(nodes, dtype=np.int64)
        self.frames = np.asarray(frames, dtype=np.float64)
        self._slot = np.full(n_dof // dim, -1, dtype=np.int64)
        self._slot[self.nodes] = np.arange(self.nodes.size)
        # rotate()'s pattern work for the index arrays it saw last (same objects: reused)
        self._pattern: tuple | None = None

    def same_as(self, other: NodeFrames) -> bool:
        """Whether ``other`` rotates the same nodes into the same frames (bit-for-bit)."""
        return (
            self.dim == other.dim
            and self.n_dof == other.n_dof
            and np.array_equal(self.nodes, other.nodes)
            and np.array_equal(self.frames, other.frames)
        )

    def to_local(self, x: np.ndarray) -> np.ndarray:
        """y ``(n_dof,)`` with y_i = Q_i^T x_i on rotated nodes (also maps gradients)."""
        y = x.copy().reshape(-1, self.dim)
        y[self.nodes] = np.einsum("rji,rj->ri", self.frames, y[self.nodes])
        return y.reshape(-1)

    def to_global(self, y: np.ndarray) -> np.ndarray:
        """x ``(n_dof,)`` with x_i = Q_i y_i on rotated nodes."""
        x = y.copy().reshape(-1, self.dim)
        x[self.nodes] = np.einsum("rij,rj->ri", self.frames, x[self.nodes])
        return x.reshape(-1)

    def normal_dofs(self) -> np.ndarray:
        """DOF indices ``(r,)`` of the first local axis (the normal) of each rotated node."""
        return self.nodes * self.dim

    def rotate(self, t: Triplets) -> Triplets:
        """Triplets of Q^T H Q from those of H (entries touching rotated nodes expanded).

        The index work depends only on ``t.rows``/``t.cols``; it is kept while the next call
        brings the very same array objects (a pattern fixed for the step), and then only the
        values are recomputed and the returned index arrays are the same objects again.
        """
        cached = self._pattern
        if cached is None or cached[0] is not t.rows or cached[1] is not t.cols:
            pattern = self._rotated_pattern(t.rows, t.cols)
            cached = self._pattern = (t.rows, t.cols, *pattern, new_pattern_key())
        touched, coef, rows, cols, key = cached[2:]
        if touched is None:
            return t
        vals = t.vals[touched][:, None, None] * coef
        vals = np.concatenate([t.vals[~touched], vals.reshape(-1)])
        return Triplets(rows, cols, vals, pattern_key=key)  # rows, cols: kept here, never edited

    def _rotated_pattern(self, r_all: np.ndarray, c_all: np.ndarray) -> tuple:
        """(touched mask, coefficients (m, d, d), rows, cols) of the rotation of a pattern."""
        d = self.dim
        row_slot = self._slot[r_all // d]
        col_slot = self._slot[c_all // d]
        touched = (row_slot >= 0) | (col_slot >= 0)
        if not touched.any():
            return None, None, r_all, c_all
        r, c = r_all[touched], c_all[touched]
        rs, cs = row_slot[touched], col_slot[touched]
        # coefficient of local axis a for the row: Q_i[rho, a] if rotated, else delta(rho, a)
        row_coef = np.where(
            (rs >= 0)[:, None], self.frames[np.maximum(rs, 0), r % d, :], np.eye(d)[r % d]
        )
        col_coef = np.where(
            (cs >= 0)[:, None], self.frames[np.maximum(cs, 0), c % d, :], np.eye(d)[c % d]
        )
        comp = np.arange(d)
        rows = ((r // d) * d)[:, None, None] + comp[None, :, None] + 0 * comp[None, None, :]
        cols = ((c // d) * d)[:, None, None] + comp[None, None, :] + 0 * comp[None, :, None]
        coef = row_coef[:, :, None] * col_coef[:, None, :]
        return (
            touched,
            coef,
            np.concatenate([r_all[~touched], rows.reshape(-1)]),
            np.concatenate([c_all[~touched], cols.reshape(-1)]),
        )
