"""Gravity: the potential -sum_i m_i g . x_i of the unknown nodes (part of B-bar in eq. 10)."""

from __future__ import annotations

import numpy as np

from bfemp.terms.base import StepContext, empty_triplets
from solvers.assembly import Triplets

__all__ = ["GravityTerm"]


class GravityTerm:
    """Uniform gravity ``g (d,)`` in m/s^2 acting on the lumped masses of the unknowns."""

    name = "gravity"

    def __init__(self, gravity: np.ndarray) -> None:
        self.gravity = np.asarray(gravity, dtype=np.float64)

    def begin_step(self, ctx: StepContext) -> None:
        """Force per DOF ``m_i g`` in N, shape ``(n_dof,)``."""
        g = np.tile(self.gravity, ctx.layout.n_dof_nodes)
        self._force = ctx.dof_mass * g

    def solution_changed(self, x: np.ndarray) -> None:
        """Nothing to cache."""

    def value(self, x: np.ndarray) -> float:
        """Potential energy in J."""
        return -float(np.dot(self._force, x))

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """``-m g``, shape ``(n_dof,)``."""
        return -self._force

    def hessian(self, x: np.ndarray, psd: bool) -> Triplets:
        """Zero (linear potential)."""
        return empty_triplets()

    def max_step_size(self, x: np.ndarray, p: np.ndarray) -> float:
        """No feasibility constraint."""
        return 1.0
