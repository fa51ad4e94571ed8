"""The incremental potential of one implicit step (BFEMP eq. 22, with contact BFEMP eq. 38):

    E(x) = 1/2 ||x - x_hat||_M^2 + 2 alpha beta dt^2 (Psi(x) + gravity + contact + friction).

This is the only place where terms are summed and where the weights are applied: 2 alpha beta
dt^2, and for the contact terms (those with ``contact = True``: barrier, friction) the
integrator's ``contact_weight`` (alpha dt^2 under ``"newmark_implicit_contact"``).
It implements the objective protocol of ``solvers.newton.minimize``. With ``frames`` (slip
boundaries) the solver's unknowns are y, x = Q y, and the normal coordinates are fixed DOFs.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

from bfemp.frames import NodeFrames
from bfemp.mpm._transfer_kernels import _largest_particle_increment
from bfemp.terms.base import StepContext, Term
from solvers.assembly import Triplets, TripletStacker

__all__ = ["IncrementalPotential", "is_contact"]


def is_contact(term: Term) -> bool:
    """Whether a term is a contact force (barrier, friction): its ``contact`` attribute."""
    return bool(getattr(term, "contact", False))


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
        self.contact_weight = 1.0
        self._weights = [1.0] * len(self.potentials)
        self.fixed_dofs: np.ndarray | None = None
        self.frames: NodeFrames | None = None
        self._particles: tuple | None = None  # (nodes, weights, grads, node offset, dx)
        # stacks the terms' triplets, reusing the stacked index arrays of a fixed pattern
        self._stacker = TripletStacker()
        self._hessian_s: dict[str, float] = {}  # see hessian_seconds

    @property
    def terms(self) -> list[Term]:
        """Inertia first, then the potentials."""
        return [self.inertia, *self.potentials]

    def begin_step(
        self,
        ctx: StepContext,
        weight: float,
        frames: NodeFrames | None = None,
        contact_weight: float | None = None,
    ) -> None:
        """Start a step; ``weight`` = 2 alpha beta dt^2 in s^2 (BFEMP eq. 22), ``contact_weight``
        that of the contact terms (default: ``weight``); optional slip frames."""
        self.weight = float(weight)
        self.contact_weight = self.weight if contact_weight is None else float(contact_weight)
        self._weights = [
            self.contact_weight if is_contact(term) else self.weight for term in self.potentials
        ]
        self.n_dof = ctx.layout.n_dof
        self._layout = ctx.layout
        self._particles = None
        if ctx.mpm is not None:
            st = ctx.mpm.stencils
            spacing = ctx.model.grid.dx
            self._particles = (st.nodes, st.weights, st.grads, ctx.mpm.node_offset, spacing)
        frames = frames if frames is not None and frames.nodes.size else None
        if frames is not None and self.frames is not None and frames.same_as(self.frames):
            frames = self.frames  # the last step's frames, with their rotated pattern kept
        self.frames = frames
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
        for weight, term in zip(self._weights, self.potentials, strict=True):
            total += weight * term.value(x)
        return total

    def gradient(self, y: np.ndarray) -> np.ndarray:
        """dE/dy ``(n_dof,)`` at the current iterate."""
        x = self._x
        g = self.inertia.gradient(x)
        for weight, term in zip(self._weights, self.potentials, strict=True):
            g += weight * term.gradient(x)
        return self.to_unknowns(g)

    def potential_gradient(self, x: np.ndarray, contact: bool | None = None) -> np.ndarray:
        """Unweighted gradient of the potentials ``(n_dof,)`` in N (minus the total force).

        ``contact``: None sums every potential, True only the contact terms, False the others.
        """
        g = np.zeros(self.n_dof)
        for term in self.potentials:
            if contact is None or is_contact(term) == contact:
                g += term.gradient(x)
        return g

    def hessian(self, y: np.ndarray, psd: bool) -> Triplets:
        """All terms' triplets (potentials scaled by the weight), in the unknowns' frames."""
        x = self._x
        clock = self._hessian_s
        started = time.perf_counter()
        parts = [self.inertia.hessian(x, psd)]
        now = time.perf_counter()
        clock["inertia"] = clock.get("inertia", 0.0) + now - started
        started = now
        for weight, term in zip(self._weights, self.potentials, strict=True):
            t = term.hessian(x, psd)
            parts.append(Triplets(t.rows, t.cols, weight * t.vals))
            now = time.perf_counter()
            clock[term.name] = clock.get(term.name, 0.0) + now - started
            started = now
        total = self._stacker.stack(parts)
        total = total if self.frames is None else self.frames.rotate(total)
        clock["stack"] = clock.get("stack", 0.0) + time.perf_counter() - started
        return total

    def hessian_seconds(self) -> dict[str, float]:
        """Wall time in s spent in :meth:`hessian` since construction, by part: each potential's
        name (terms of one name summed; the weighting included), ``"inertia"``, ``"stack"``
        (stacking and rotating the triplets) and ``"<name>/<phase>"`` for a term that times its
        phases (``hessian_seconds`` attribute: the elasticity terms' ``dpdf`` and
        ``projection``). A step's split is the difference of two calls; the parts without a
        ``/`` add up to Newton's ``hessian`` phase."""
        out = dict(self._hessian_s)
        for term in self.potentials:
            for phase, seconds in getattr(term, "hessian_seconds", {}).items():
                key = f"{term.name}/{phase}"
                out[key] = out.get(key, 0.0) + seconds
        return out

    def increment_norm(self, p: np.ndarray) -> float:
        """Size of an increment p of the unknowns ``(n_dof,)`` for Newton's stopping rule, in m.

        The largest change it makes to what the step hands on: a FEM node's position, an MPM
        particle's position (particles are the B-spline images of the grid nodes, so particle p
        moves by sum_i w_ip p_i) and its deformation gradient, as dx |sum_i p_i grad w_ip^T|
        (F^{n+1} = (I + sum_i (x_i - X_i) grad w_ip^T) F^n; grad w is the APIC C's weight too).
        Not max_i |p_i| over grid nodes (the paper's ||p||_inf): a node that particles reach
        only with weights w ~ 1e-12 has a mass and a stiffness ~1e-12 of its neighbours', so its
        increment p_i = g_i / H_ii is round-off amplified ~1e12 and moves nothing (w ~ 1e-12,
        dx grad w ~ 1e-6; design note ``measurements``, newton).
        """
        dx = self.to_positions(p)
        if self._particles is None:
            return float(np.abs(dx).max(initial=0.0))
        nodes, weights, grads, offset, spacing = self._particles
        moved = self._layout.expand(dx)
        grid = np.ascontiguousarray(moved[offset:])
        particles = _largest_particle_increment(grid, nodes, weights, grads, float(spacing))
        return float(max(np.abs(moved[:offset]).max(initial=0.0), particles))

    def max_step_size(self, y: np.ndarray, p: np.ndarray) -> float:
        """The smallest feasibility bound over the terms (paths are linear in x as in y)."""
        x, px = self._x, self.to_positions(p)
        return min(term.max_step_size(x, px) for term in self.terms)
