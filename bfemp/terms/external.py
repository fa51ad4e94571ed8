"""Constant external nodal forces: the potential -sum_i f_i . x_i (the traction term of eq. 10)."""

from __future__ import annotations

import numpy as np

from bfemp.terms.base import StepContext, empty_triplets
from solvers.assembly import Triplets

__all__ = ["ExternalForceTerm"]


class ExternalForceTerm:
    """Dead loads ``f (n_all, d)`` in N (N/m in 2D); loads on prescribed nodes do no work."""

    name = "external_force"

    def __init__(self, node_forces: np.ndarray) -> None:
        self.node_forces = np.asarray(node_forces, dtype=np.float64)

    def begin_step(self, ctx: StepContext) -> None:
        """Restrict the loads to the unknowns ``(n_dof,)``."""
        full = np.zeros((ctx.layout.n_all, ctx.layout.dim))
        full[: self.node_forces.shape[0]] = self.node_forces
        self._force = ctx.layout.restrict(full)

    def solution_changed(self, x: np.ndarray) -> None:
        """Nothing to cache."""

    def value(self, x: np.ndarray) -> float:
        """Potential of the loads in J."""
        return -float(np.dot(self._force, x))

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """``-f``, shape ``(n_dof,)``."""
        return -self._force

    def hessian(self, x: np.ndarray, psd: bool) -> Triplets:
        """Zero (linear potential)."""
        return empty_triplets()

    def max_step_size(self, x: np.ndarray, p: np.ndarray) -> float:
        """No feasibility constraint."""
        return 1.0
