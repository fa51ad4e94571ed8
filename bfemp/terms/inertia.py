"""Inertia: 1/2 ||x - x_hat||^2_M with lumped masses (first term of BFEMP eq. 22)."""

from __future__ import annotations

import numpy as np

from bfemp.terms.base import StepContext
from solvers.assembly import Triplets

__all__ = ["InertiaTerm"]


class InertiaTerm:
    """``E(x) = 1/2 sum_i m_i |x_i - x_hat_i|^2`` in J; Hessian diag(m)."""

    name = "inertia"

    def begin_step(self, ctx: StepContext) -> None:
        """Take x_hat ``(n_dof,)`` m and the lumped DOF masses ``(n_dof,)`` kg of this step."""
        self._x_hat = ctx.x_hat
        self._mass = ctx.dof_mass
        n = ctx.layout.n_dof
        # the same index array while the size holds: the stacked pattern downstream is kept
        if getattr(self, "_diag", None) is None or self._diag.size != n:
            self._diag = np.arange(n, dtype=np.int64)

    def solution_changed(self, x: np.ndarray) -> None:
        """Nothing to cache."""

    def value(self, x: np.ndarray) -> float:
        """Kinetic-like energy in J."""
        dx = x - self._x_hat
        return 0.5 * float(np.dot(self._mass * dx, dx))

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """``M (x - x_hat)``, shape ``(n_dof,)``."""
        return self._mass * (x - self._x_hat)

    def hessian(self, x: np.ndarray, psd: bool) -> Triplets:
        """Diagonal mass matrix (already PSD)."""
        return Triplets(self._diag, self._diag, self._mass.copy())

    def max_step_size(self, x: np.ndarray, p: np.ndarray) -> float:
        """No feasibility constraint."""
        return 1.0
