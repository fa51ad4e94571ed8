"""Gravity: the potential -sum_i m_i g . x_i of the unknown nodes (in B-bar of BFEMP eq. 10)."""

from __future__ import annotations

import numpy as np

from bfemp.terms.base import StepContext
from bfemp.terms.external import ConstantForceTerm

__all__ = ["GravityTerm"]


class GravityTerm(ConstantForceTerm):
    """Uniform gravity ``g (d,)`` in m/s^2 acting on the lumped masses of the unknowns."""

    name = "gravity"

    def __init__(self, gravity: np.ndarray) -> None:
        self.gravity = np.asarray(gravity, dtype=np.float64)

    def _forces(self, ctx: StepContext) -> np.ndarray:
        """m_i g per DOF, ``(n_dof,)`` in N (grid nodes get their transferred mass)."""
        return ctx.dof_mass * np.tile(self.gravity, ctx.layout.n_dof_nodes)
