"""Elasticity: Psi(x) = sum_q V_q psi(F_q(x)) over FEM cells and (later) MPM particles
(BFEMP eq. 22).

One term serves every stencil whose deformation gradient is affine in the node positions
(ARCHITECTURE.md): FEM cells (F = Ds Dm^-1, BFEMP eq. 24) and MPM particles (F_p = (I + sum_i (x_i -
X_i) grad w_ip^T) F_p^n); only the stencil builders differ. The Hessian projects dP/dF to PSD at the
F-level (d^2 x d^2) before the chain rule, which keeps each local block PSD at a fraction of the
cost of projecting the (k d)^2 block.

``max_step_size`` returns 0.9 x the first step at which det F reaches 0 along the search direction
(section 5): every law, linear elasticity included, is kept un-inverted.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from bfemp._detf_bound import max_step_det_positive
from bfemp.model import Model
from bfemp.terms._elasticity_kernels import (
    _deformation_gradients,
    _local_hessians,
    _scatter_forces,
)
from bfemp.terms.base import StepContext, block_pattern
from solvers.assembly import Triplets

__all__ = [
    "ElasticStencils",
    "ElasticityTerm",
    "fem_cell_stencils",
    "fem_elastic_groups",
    "stencil_energy",
]

#: Fraction of the first det F = 0 step taken as the line-search start (section 5).
DET_STEP_FRACTION = 0.9


@dataclass(frozen=True)
class ElasticStencils:
    """Quadrature points whose F is affine in node positions: F_s = const_s + sum_a y_a g_a^T.

    Attributes:
        nodes: node indices ``(S, k)`` in the all-nodes numbering of ``DofLayout``.
        grads: gradients ``(S, k, d)`` in 1/m.
        const: constant part ``(S, d, d)``.
        volume: integration weights ``(S,)`` in m^d (rest cell volume, particle volume).
        mu: shear modulus (Lame mu) ``(S,)`` in Pa.
        lam: Lame lambda ``(S,)`` in Pa.
    """

    nodes: np.ndarray
    grads: np.ndarray
    const: np.ndarray
    volume: np.ndarray
    mu: np.ndarray
    lam: np.ndarray


def fem_cell_stencils(model: Model, cell_mask: np.ndarray) -> ElasticStencils:
    """Stencils of the FEM cells selected by ``cell_mask (M,)`` (F = sum_a x_a grad N_a^T)."""
    cells = np.flatnonzero(cell_mask)
    d = model.dim
    bodies = model.fem_cell_body[cells]
    mu_b = np.array([b.material.mu for b in model.fem_bodies])
    lam_b = np.array([b.material.lam for b in model.fem_bodies])
    return ElasticStencils(
        nodes=np.ascontiguousarray(model.fem_cells[cells]),
        grads=np.ascontiguousarray(model.fem_cell_grad[cells]),
        const=np.zeros((cells.size, d, d)),
        volume=np.ascontiguousarray(model.fem_cell_volume[cells]),
        mu=mu_b[bodies],
        lam=lam_b[bodies],
    )


def fem_elastic_groups(model: Model) -> list[tuple[object, ElasticStencils]]:
    """The FEM cells that can deform, one stencil set per material law (in body order).

    Cells whose every node is scripted are left out: they add nothing to a minimisation and,
    scripted motions being rigid, store no energy. The barrier strategy's potential and the
    metrics' elastic energy both use these groups.
    """
    moving = ~np.all(model.fem_prescribed[model.fem_cells], axis=1)
    laws = {id(b.material.law): b.material.law for b in model.fem_bodies}
    groups = []
    for law in laws.values():
        bodies = [b.index for b in model.fem_bodies if b.material.law is law]
        mask = np.isin(model.fem_cell_body, bodies) & moving
        if mask.any():
            groups.append((law, fem_cell_stencils(model, mask)))
    return groups


def stencil_energy(law: object, stencils: ElasticStencils, node_positions: np.ndarray) -> float:
    """sum_s V_s psi(F_s) in J (J/m in 2D) of ``stencils`` at all-node positions ``(n, d)``."""
    st = stencils
    F = _deformation_gradients(node_positions, st.nodes, st.grads, st.const)
    return float(np.dot(st.volume, law.energy_density(F, st.mu, st.lam)))


class ElasticityTerm:
    """Hyperelastic energy of a set of stencils sharing one material law.

    Args:
        law: pointwise law with ``energy_density``, ``first_piola``, ``first_piola_derivative``.
        stencils: a fixed ``ElasticStencils`` or a callable ``ctx -> ElasticStencils`` evaluated at
            every ``begin_step`` (MPM particles).
        name: name shown in ``Simulation.terms``.
    """

    def __init__(
        self,
        law: object,
        stencils: ElasticStencils | Callable[[StepContext], ElasticStencils],
        name: str = "elasticity",
    ) -> None:
        self.law = law
        self.name = name
        self._source = stencils
        self._pattern_key: tuple[int, int] | None = None
        self._dofs: np.ndarray | None = None
        #: s spent in the Hessian's sub-phases since construction (``IncrementalPotential``
        #: reports them per step): ``dpdf`` (dP/dF), ``projection`` (its PSD projection)
        self.hessian_seconds = {"dpdf": 0.0, "projection": 0.0}
        if isinstance(stencils, ElasticStencils):
            self.stencils = stencils

    # ---------------------------------------------------------------- step set-up
    def begin_step(self, ctx: StepContext) -> None:
        """Refresh stencils (if they move) and the DOF pattern of the local blocks."""
        fresh = self._source(ctx) if callable(self._source) else self._source
        layout = ctx.layout
        key = (id(fresh), id(layout))
        if key != self._pattern_key:
            self.stencils = fresh
            dofs = layout.stencil_dofs(fresh.nodes)
            # A new layout each step usually numbers the DOFs as the last one did: then the
            # pattern arrays are kept, and with them the stacked and assembled patterns
            # downstream (TripletStacker, TripletAssembler), which key on these very arrays.
            if self._dofs is None or not np.array_equal(dofs, self._dofs):
                self._rows, self._cols, self._keep = block_pattern(dofs)
                self._dofs = dofs
            self._pattern_key = key
        self._layout = layout
        self._fixed = ctx.fixed_positions

    def solution_changed(self, x: np.ndarray) -> None:
        """Deformation gradients ``(S, d, d)`` at ``x``."""
        y = self._layout.positions(x, self._fixed)
        st = self.stencils
        self._F = _deformation_gradients(y, st.nodes, st.grads, st.const)

    def value(self, x: np.ndarray) -> float:
        """``sum_s V_s psi(F_s)`` in J; +inf where some det F <= 0 (Neo-Hookean)."""
        st = self.stencils
        return float(np.dot(st.volume, self.law.energy_density(self._F, st.mu, st.lam)))

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """``dPsi/dx (n_dof,)`` in N."""
        st = self.stencils
        pv = self.law.first_piola(self._F, st.mu, st.lam) * st.volume[:, None, None]
        forces = np.zeros((self._layout.n_all, self._layout.dim))
        _scatter_forces(forces, st.nodes, st.grads, pv)
        return self._layout.restrict(forces)

    def _piola_derivative(self, psd: bool) -> np.ndarray:
        """dP/dF at the current F as symmetric ``(S, d^2, d^2)`` blocks in Pa (entry
        ``[s, i d + m, j d + l]`` = dP_im/dF_jl), projected to PSD at the F-level when ``psd``."""
        st = self.stencils
        d = self._layout.dim
        started = time.perf_counter()
        dpdf = self.law.first_piola_derivative(self._F, st.mu, st.lam)
        dpdf = np.ascontiguousarray(dpdf.reshape(-1, d * d, d * d))
        projected = time.perf_counter()
        self.hessian_seconds["dpdf"] += projected - started
        if psd:
            dpdf = self.law.project_derivative(dpdf, self._F, st.mu, st.lam)
            self.hessian_seconds["projection"] += time.perf_counter() - projected
        return dpdf

    def hessian(self, x: np.ndarray, psd: bool) -> Triplets:
        """Local (k d)^2 blocks, dP/dF projected to PSD at the F-level when ``psd``."""
        st = self.stencils
        blocks = _local_hessians(self._piola_derivative(psd), st.grads, st.volume)
        return Triplets(self._rows, self._cols, blocks.reshape(-1)[self._keep])

    def max_step_size(self, x: np.ndarray, p: np.ndarray) -> float:
        """0.9 x the first alpha with det F(x + alpha p) = 0 (section 5); 1 when none in (0, 1]."""
        st = self.stencils
        direction = self._layout.expand(p)
        dF = _deformation_gradients(direction, st.nodes, st.grads, np.zeros_like(st.const))
        alpha = max_step_det_positive(self._F, dF, alpha_max=1.0 / DET_STEP_FRACTION)
        return min(1.0, DET_STEP_FRACTION * alpha)
