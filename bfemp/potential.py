"""The incremental potential of one implicit step (BFEMP paper eq. 22, with contact eq. 38):

    E(x) = 1/2 ||x - x_hat||_M^2 + 2 alpha beta dt^2 (Psi(x) + gravity + contact + friction).

This is the only place where terms are summed and where the weight 2 alpha beta dt^2 is applied.
It implements the objective protocol of ``solvers.newton.minimize``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bfemp.terms.base import StepContext, Term
from solvers.assembly import Triplets

__all__ = ["IncrementalPotential"]


class IncrementalPotential:
    """``inertia + weight * sum(potentials)`` over the unknowns of a step.

    Args:
        inertia: the inertia term (unweighted).
        potentials: the potential-energy terms (each unweighted; weighted here).
    """

    def __init__(self, inertia: Term, potentials: Sequence[Term]) -> None:
        self.inertia = inertia
        self.potentials = list(potentials)
        self.weight = 1.0
        self.fixed_dofs: np.ndarray | None = None

    @property
    def terms(self) -> list[Term]:
        """Inertia first, then the potentials."""
        return [self.inertia, *self.potentials]

    def begin_step(self, ctx: StepContext, weight: float) -> None:
        """Start a step; ``weight`` = 2 alpha beta dt^2 in s^2 (eq. 22)."""
        self.weight = float(weight)
        self.n_dof = ctx.layout.n_dof
        for term in self.terms:
            term.begin_step(ctx)

    def solution_changed(self, x: np.ndarray) -> None:
        """Forward a new iterate ``x (n_dof,)`` to every term."""
        for term in self.terms:
            term.solution_changed(x)

    def value(self, x: np.ndarray) -> float:
        """E(x) in J."""
        total = self.inertia.value(x)
        for term in self.potentials:
            total += self.weight * term.value(x)
        return total

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """dE/dx ``(n_dof,)``."""
        return self.inertia.gradient(x) + self.weight * self.potential_gradient(x)

    def potential_gradient(self, x: np.ndarray) -> np.ndarray:
        """Unweighted gradient of the potentials ``(n_dof,)`` in N (minus the total force)."""
        g = np.zeros(self.n_dof)
        for term in self.potentials:
            g += term.gradient(x)
        return g

    def hessian(self, x: np.ndarray, psd: bool) -> Triplets:
        """All terms' triplets, potentials scaled by the weight."""
        parts = [self.inertia.hessian(x, psd)]
        for term in self.potentials:
            t = term.hessian(x, psd)
            parts.append(Triplets(t.rows, t.cols, self.weight * t.vals))
        return Triplets.concatenate(parts)

    def max_step_size(self, x: np.ndarray, p: np.ndarray) -> float:
        """The smallest feasibility bound over the terms."""
        return min(term.max_step_size(x, p) for term in self.terms)
