"""Elasticity of MPM particles: the same term as FEM cells, other stencils (ARCHITECTURE.md).

F_p(x) = sum_i x_i (grad w_ip)^T F_p^n (BFEMP eq. 25) is affine in the grid-node end positions
x_i, so F_p = C_p + sum_i x_i g_ip^T with g_ip = (F_p^n)^T grad w_ip and C_p = F_p^n - sum_i x_i^n
g_ip^T (zero up to round-off by linear completeness). The energy is sum_p V_p^0 psi(F_p).

Only the Hessian assembly differs from FEM cells: blocks are accumulated per (grid node, relative
offset) in numba, so the (3^d d)^2 per-particle block list is never built.
"""

from __future__ import annotations

import numba
import numpy as np

from bfemp.mpm._hessian_kernels import (
    _accumulate_blocks,
    _effective_gradients,
    _neighbour_table,
    _pair_pattern,
)
from bfemp.terms.base import StepContext
from bfemp.terms.elasticity import ElasticityTerm, ElasticStencils
from geometry.grid import stencil_offsets
from solvers.assembly import Triplets

__all__ = ["MpmElasticityTerm", "mpm_particle_stencils", "pair_codes"]


def pair_codes(dim: int) -> np.ndarray:
    """(K, K) code in [0, 5^d) of the relative offset o_b - o_a of stencil entries a, b."""
    off = stencil_offsets(dim)
    rel = off[None, :, :] - off[:, None, :] + 2  # in {0..4}^d
    return np.ravel_multi_index(tuple(np.moveaxis(rel, -1, 0)), (5,) * dim).astype(np.int64)


def mpm_particle_stencils(
    ctx: StepContext, particles: np.ndarray, mu: np.ndarray, lam: np.ndarray
) -> ElasticStencils:
    """Elastic stencils of the selected particles ``(p,)`` for this step (grid-offset nodes)."""
    mpm = ctx.mpm
    st = mpm.stencils
    # g = F^nT grad w and the constant part C (module docstring), in one numba pass
    grads, const = _effective_gradients(
        ctx.state.mpm_F, st.grads, st.nodes, st.active_x, np.asarray(particles, dtype=np.int64)
    )
    nodes = st.nodes[particles]
    return ElasticStencils(
        nodes=np.ascontiguousarray(nodes + mpm.node_offset),
        grads=np.ascontiguousarray(grads),
        const=np.ascontiguousarray(const),
        volume=np.ascontiguousarray(ctx.model.mpm_volume[particles]),
        mu=mu,
        lam=lam,
    )


class MpmElasticityTerm(ElasticityTerm):
    """Elastic energy of MPM particles of one material law (stencils rebuilt every step).

    Args:
        law: the pointwise material law.
        particles: indices ``(p,)`` of the particles with this law.
        mu, lam: their Lame parameters ``(p,)`` in Pa.
    """

    def __init__(
        self, law: object, particles: np.ndarray, mu: np.ndarray, lam: np.ndarray, name: str
    ) -> None:
        super().__init__(law, lambda ctx: mpm_particle_stencils(ctx, particles, mu, lam), name)
        self.particles = particles

    def begin_step(self, ctx: StepContext) -> None:
        """New stencils at x^n and the node-pair pattern of this step's active grid."""
        self.stencils = self._source(ctx)
        self._layout = ctx.layout
        self._fixed = ctx.fixed_positions
        st = ctx.mpm.stencils
        d = ctx.layout.dim
        self._n_codes = 5**d
        self._codes = pair_codes(d)
        self._local_nodes = np.ascontiguousarray(st.nodes[self.particles])
        self._weights = np.ascontiguousarray(st.weights[self.particles])
        self._n_grid = st.n_nodes
        nbr = _neighbour_table(
            self._local_nodes,
            self._weights,
            self.stencils.grads,
            self._codes,
            self._n_grid,
            self._n_codes,
        )
        self._nbr = nbr
        # rows/cols of every (node, offset) d x d block; prescribed (sticky) DOFs dropped
        offset = ctx.mpm.node_offset
        dof_grid = np.ascontiguousarray(ctx.layout.dof_node[offset : offset + self._n_grid])
        rows, cols, self._keep = _pair_pattern(nbr, dof_grid, d)
        # views with numpy's own int64 dtype object: Triplets' np.ascontiguousarray(dtype=int64)
        # then hands these very arrays on (numba's returned dtype instance would make it wrap
        # a new view each call, and the patterns downstream, keyed on identity, rebuilt)
        rows, cols = rows.view(np.int64), cols.view(np.int64)
        # Where the active grid and its node pairs are those of the last step (a body at rest
        # or moving within its cells), the last arrays are kept: the stacked, rotated and
        # assembled patterns downstream key on these very objects and are reused.
        last = getattr(self, "_rows", None)
        if not (
            last is not None and np.array_equal(rows, last) and np.array_equal(cols, self._cols)
        ):
            self._rows, self._cols = rows, cols

    def hessian(self, x: np.ndarray, psd: bool) -> Triplets:
        """Node-pair blocks accumulated over particles, dP/dF projected to PSD when ``psd``."""
        st = self.stencils
        blocks = _accumulate_blocks(
            self._local_nodes,
            self._weights,
            st.grads,
            self._piola_derivative(psd),
            st.volume,
            self._codes,
            self._nbr,
            self._n_grid,
            self._n_codes,
            max(1, min(numba.get_num_threads(), st.nodes.shape[0] // 256)),
        )
        return Triplets(self._rows, self._cols, blocks.reshape(-1)[self._keep])
