"""Constant forces on the unknowns: the linear potential -f . x (the B-bar terms of BFEMP eq. 10).

``ConstantForceTerm`` is the shared mechanism; gravity (m_i g per node) and dead loads (given
nodal forces) only differ in how they build f at the start of a step.
"""

from __future__ import annotations

import numpy as np

from bfemp.terms.base import StepContext
from solvers.assembly import Triplets

__all__ = ["ConstantForceTerm", "ExternalForceTerm"]


class ConstantForceTerm:
    """E(x) = -f . x with a force f ``(n_dof,)`` in N fixed during a step (subclasses set it)."""

    name = "constant_force"

    def _forces(self, ctx: StepContext) -> np.ndarray:
        raise NotImplementedError

    def begin_step(self, ctx: StepContext) -> None:
        """The force on each unknown, ``(n_dof,)`` in N."""
        self._force = self._forces(ctx)

    def solution_changed(self, x: np.ndarray) -> None:
        """Nothing to cache."""

    def value(self, x: np.ndarray) -> float:
        """Potential energy in J."""
        return -float(np.dot(self._force, x))

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """``-f``, shape ``(n_dof,)``."""
        return -self._force

    def hessian(self, x: np.ndarray, psd: bool) -> Triplets:
        """Zero (linear potential)."""
        return Triplets.empty()

    def max_step_size(self, x: np.ndarray, p: np.ndarray) -> float:
        """No feasibility constraint."""
        return 1.0


class ExternalForceTerm(ConstantForceTerm):
    """Dead loads ``f (n_all, d)`` in N (N/m in 2D); loads on prescribed nodes do no work."""

    name = "external_force"

    def __init__(self, node_forces: np.ndarray) -> None:
        self.node_forces = np.asarray(node_forces, dtype=np.float64)

    def _forces(self, ctx: StepContext) -> np.ndarray:
        full = np.zeros((ctx.layout.n_all, ctx.layout.dim))
        full[: self.node_forces.shape[0]] = self.node_forces
        return ctx.layout.restrict(full)
