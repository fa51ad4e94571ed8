"""Which node positions are unknowns of an implicit step, and how they are flattened.

Node numbering ("all nodes") used by every energy term: FEM nodes ``[0, N)`` then the active MPM
grid nodes ``[N, N + G)``. Unknowns are the free nodes among them, flattened interleaved into
``x (n_dof,) = [x_0, y_0, (z_0,) x_1, ...]`` in m. Prescribed FEM nodes are not unknowns: their
positions at the end of the step are known and supplied by ``fixed_positions``.

A ``DofLayout`` is rebuilt every step (the active grid changes as particles move).
"""

from __future__ import annotations

import numpy as np

__all__ = ["DofLayout"]


class DofLayout:
    """Map between the unknown vector ``x (n_dof,)`` and all node positions ``(n_all, d)``.

    Args:
        dim: spatial dimension.
        free: bool mask ``(n_all,)`` of the nodes whose positions are unknowns.
        n_fem: number of FEM nodes (the first ``n_fem`` of all nodes).
    """

    def __init__(self, dim: int, free: np.ndarray, n_fem: int) -> None:
        self.dim = dim
        self.n_all = int(free.shape[0])
        self.n_fem = int(n_fem)
        self.free_nodes = np.flatnonzero(free).astype(np.int64)
        # dof_node[i]: position of node i among the unknown nodes, -1 when prescribed.
        self.dof_node = np.full(self.n_all, -1, dtype=np.int64)
        self.dof_node[self.free_nodes] = np.arange(self.free_nodes.size)
        self.n_dof_nodes = int(self.free_nodes.size)
        self.n_dof = self.n_dof_nodes * dim

    def positions(self, x: np.ndarray, fixed_positions: np.ndarray) -> np.ndarray:
        """All node positions ``(n_all, d)``: free ones from ``x (n_dof,)``, the rest fixed."""
        y = fixed_positions.copy()
        y[self.free_nodes] = x.reshape(-1, self.dim)
        return y

    def restrict(self, node_values: np.ndarray) -> np.ndarray:
        """Unknown-vector entries ``(n_dof,)`` of a per-node array ``(n_all, d)``."""
        return np.ascontiguousarray(node_values[self.free_nodes]).reshape(-1)

    def expand(self, x: np.ndarray) -> np.ndarray:
        """Per-node array ``(n_all, d)`` with ``x (n_dof,)`` at free nodes and zero elsewhere."""
        out = np.zeros((self.n_all, self.dim))
        out[self.free_nodes] = x.reshape(-1, self.dim)
        return out

    def stencil_dofs(self, nodes: np.ndarray) -> np.ndarray:
        """Global DOF indices ``(S, k * d)`` of stencils ``nodes (S, k)``; -1 for prescribed DOFs.

        Local DOF ``a * d + i`` of a stencil is component ``i`` of its node ``a``.
        """
        node_dof = self.dof_node[nodes]  # (S, k)
        comp = np.arange(self.dim)
        dofs = node_dof[:, :, None] * self.dim + comp
        dofs[node_dof < 0] = -1
        return dofs.reshape(nodes.shape[0], -1)
