"""Friction coefficients per pair of bodies (``scene.set_friction``).

``scene.set_contact(mu=...)`` gives every contact pair one Coulomb coefficient; a scene with a
no-slip plate pressing two bodies that rub at mu = 0.2 (BFEMP section 6.6: the plate at
mu = 10, the rings at 0, 0.2, 0.5) needs one per pair of bodies. A contact's bodies are those of
its two ends: the point (a particle or a FEM boundary node) and the feature it is closest to
(a FEM boundary vertex, edge or face), both known to the collision set as ``point_body`` codes
(FEM bodies 0, 1, ...; MPM bodies -1 - index).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["PairFriction", "body_code"]


def body_code(kind: str, index: int) -> int:
    """The collision set's code of a body: FEM body ``index`` -> index, MPM -> -1 - index."""
    if kind not in ("fem", "mpm"):
        raise ValueError(f"body kind must be 'fem' or 'mpm', got {kind!r}")
    return int(index) if kind == "fem" else -1 - int(index)


@dataclass(frozen=True)
class PairFriction:
    """A default Coulomb coefficient and overrides for pairs of bodies.

    Attributes:
        default: mu of every pair without an override (dimensionless, >= 0).
        overrides: ``((code_a, code_b, mu), ...)`` with body codes as in
            :func:`body_code`; the order within a pair does not matter.
    """

    default: float
    overrides: tuple[tuple[int, int, float], ...] = ()

    def __post_init__(self) -> None:
        for mu in (self.default, *(m for _, _, m in self.overrides)):
            if not (math.isfinite(mu) and mu >= 0.0):
                raise ValueError(f"friction coefficient must be finite and >= 0, got {mu!r}")

    @property
    def largest(self) -> float:
        """The largest coefficient of any pair (0: no friction anywhere)."""
        return max([self.default, *(m for _, _, m in self.overrides)])

    def of(self, body_a: np.ndarray, body_b: np.ndarray) -> np.ndarray:
        """mu ``(n,)`` of contacts between bodies ``body_a (n,)`` and ``body_b (n,)`` (codes)."""
        body_a, body_b = np.asarray(body_a), np.asarray(body_b)
        mu = np.full(body_a.shape, self.default)
        for a, b, value in self.overrides:  # a loop over body pairs (a few), not contacts
            mu[((body_a == a) & (body_b == b)) | ((body_a == b) & (body_b == a))] = value
        return mu
