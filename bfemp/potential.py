"""The incremental potential of one implicit step (BFEMP paper eq. 22, with contact eq. 38):

    E(x) = 1/2 ||x - x_hat||_M^2 + 2 alpha beta dt^2 (Psi(x) + gravity + contact + friction).

This is the only place where terms are summed and where the weight 2 alpha beta dt^2 is applied.
It implements the objective protocol of ``solvers.newton.minimize``. With ``frames`` (slip
boundaries) the solver's unknowns are y, x = Q y, and the normal coordinates are fixed DOFs.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bfemp.frames import NodeFrames
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
        self.frames: NodeFrames | None = None

    @property
    def terms(self) -> list[Term]:
        """Inertia first, then the potentials."""
        return [self.inertia, *self.potentials]

    def begin_step(self, ctx: StepContext, weight: float, frames: NodeFrames | None = None) -> None:
        """Start a step; ``weight`` = 2 alpha beta dt^2 in s^2 (eq. 22); optional slip frames."""
        self.weight = float(weight)
        self.n_dof = ctx.layout.n_dof
        self.frames = frames if frames is not None and frames.nodes.size else None
        self.fixed_dofs = None
        if self.frames is not None:
            self.fixed_dofs = np.zeros(self.n_dof, dtype=bool)
            self.fixed_dofs[self.frames.normal_dofs()] = True
        for term in self.terms:
            term.begin_step(ctx)

    def to_unknowns(self, x: np.ndarray) -> np.ndarray:
        """The solver's unknowns y ``(n_dof,)`` of positions x (identity without frames)."""
        return x if self.frames is None else self.frames.to_local(x)

    def to_positions(self, y: np.ndarray) -> np.ndarray:
        """Positions x ``(n_dof,)`` of the solver's unknowns y."""
        return y if self.frames is None else self.frames.to_global(y)

    def solution_changed(self, y: np.ndarray) -> None:
        """Forward a new iterate (unknowns ``y (n_dof,)``) to every term."""
        self._x = self.to_positions(y)
        for term in self.terms:
            term.solution_changed(self._x)

    def value(self, y: np.ndarray) -> float:
        """E in J at the current iterate."""
        x = self._x
        total = self.inertia.value(x)
        for term in self.potentials:
            total += self.weight * term.value(x)
        return total

    def gradient(self, y: np.ndarray) -> np.ndarray:
        """dE/dy ``(n_dof,)`` at the current iterate."""
        x = self._x
        g = self.inertia.gradient(x) + self.weight * self.potential_gradient(x)
        return self.to_unknowns(g)

    def potential_gradient(self, x: np.ndarray) -> np.ndarray:
        """Unweighted gradient of the potentials ``(n_dof,)`` in N (minus the total force)."""
        g = np.zeros(self.n_dof)
        for term in self.potentials:
            g += term.gradient(x)
        return g

    def hessian(self, y: np.ndarray, psd: bool) -> Triplets:
        """All terms' triplets (potentials scaled by the weight), in the unknowns' frames."""
        x = self._x
        parts = [self.inertia.hessian(x, psd)]
        for term in self.potentials:
            t = term.hessian(x, psd)
            parts.append(Triplets(t.rows, t.cols, self.weight * t.vals))
        total = Triplets.concatenate(parts)
        return total if self.frames is None else self.frames.rotate(total)

    def max_step_size(self, y: np.ndarray, p: np.ndarray) -> float:
        """The smallest feasibility bound over the terms (paths are linear in x as in y)."""
        x, px = self._x, self.to_positions(p)
        return min(term.max_step_size(x, px) for term in self.terms)
