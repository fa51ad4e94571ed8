"""Adaptive barrier stiffness (``kappa="auto"``), in the manner of IPC's adaptive kappa.

- Lower bound from stiffness balance: the barrier's stiffness at d = d-hat/2 on a point of weight
  omega, omega kappa b''/d-hat^2 ~ omega kappa / d-hat^2, should match the elastic stiffness of the
  patch the point stands for, E omega^{(d-2)/(d-1)} (E in 2D per unit thickness, E sqrt(omega) in
  3D): kappa_min = E_min d-hat^2 / omega^{1/(d-1)}, with E_min the softest contacting material and
  omega the mean point weight.
- When contact first appears, kappa balances the barrier gradient against the rest of the
  incremental potential's gradient (IPC's initial kappa), clamped to [kappa_min, kappa_max] with
  kappa_max = 1e4 kappa_min.
- After a step whose smallest distance fell below 0.1 d-hat and kept decreasing, kappa doubles
  (up to kappa_max), which keeps gaps resolvable in floating point.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["AdaptiveKappa"]


@dataclass
class AdaptiveKappa:
    """State of the adaptive stiffness across steps (kappa in Pa)."""

    kappa_min: float
    kappa_max: float
    kappa: float
    initialised: bool = False
    last_min_distance: float = float("inf")

    @classmethod
    def for_scene(cls, young_moduli: list[float], omega: np.ndarray, dhat: float, dim: int):  # noqa: ANN206
        """Bounds from the softest material E_min (Pa) and the mean point weight omega."""
        w = float(np.mean(omega)) if omega.size else 1.0
        kappa_min = min(young_moduli) * dhat**2 / w ** (1.0 / (dim - 1))
        return cls(kappa_min=kappa_min, kappa_max=1e4 * kappa_min, kappa=kappa_min)

    def initialise(
        self, grad_rest: np.ndarray, grad_unit_barrier: np.ndarray, weight: float
    ) -> None:
        """IPC's balance: minimise ||g_rest + weight kappa g_B1|| over kappa, then clamp."""
        gg = float(np.dot(grad_unit_barrier, grad_unit_barrier))
        if gg <= 0.0:
            return
        balance = -float(np.dot(grad_rest, grad_unit_barrier)) / (weight * gg)
        self.kappa = float(np.clip(balance, self.kappa_min, self.kappa_max))
        self.initialised = True

    def after_step(self, min_distance: float, dhat: float) -> None:
        """Double kappa when the smallest gap is below 0.1 d-hat and still closing."""
        if min_distance < 0.1 * dhat and min_distance < self.last_min_distance:
            self.kappa = min(2.0 * self.kappa, self.kappa_max)
        self.last_min_distance = min_distance
