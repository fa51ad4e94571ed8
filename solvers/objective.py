"""The energy contract of :func:`solvers.newton.minimize` (the objective's methods)."""

from __future__ import annotations

from typing import Protocol

import numpy as np

from solvers.assembly import Triplets

__all__ = ["Objective"]


class Objective(Protocol):
    """The energy contract :func:`minimize` relies on (units: J for E, x in m typically).

    An optional attribute ``fixed_dofs: np.ndarray | None`` (bool mask (n,)) marks DOFs held at
    their ``x0`` value; it is read with ``getattr(objective, "fixed_dofs", None)``. An optional
    method ``increment_norm(p) -> float`` (p (n,), zero on fixed DOFs) replaces ``||p||_inf`` in
    the stopping rule (e.g. measured on what the unknowns move, not on the unknowns).
    """

    def solution_changed(self, x: np.ndarray) -> None:
        """Called once per new iterate x (n,) (line-search trials too), before value/gradient/
        hessian at that x: refresh x-dependent caches."""
        ...

    def value(self, x: np.ndarray) -> float:
        """Energy E(x); may be inf outside the feasible set."""
        ...

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """dE/dx (n,)."""
        ...

    def hessian(self, x: np.ndarray, psd: bool) -> Triplets:
        """d2E/dx2 as COO triplets (full symmetric), per-stencil PSD-projected when ``psd``."""
        ...

    def max_step_size(self, x: np.ndarray, p: np.ndarray) -> float:
        """Largest feasible step along p (n,) from x: a value in (0, 1], or larger."""
        ...
